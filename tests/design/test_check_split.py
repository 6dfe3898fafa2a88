"""hcmt.design.check split by job: its public names stay importable from it, each from its own module."""

import importlib

import hcmt.design.check as check

MOVED = {
    "hcmt.design.prediction": ("Prediction", "design_trajectory", "predict", "summarize", "check_design_list"),
    "hcmt.design.calls": (
        "TRUST",
        "TRUSTS",
        "MODEL_BAND",
        "trusted_interval",
        "call_of",
        "add_calls",
        "final_calls",
        "add_margin",
    ),
    "hcmt.design.verification": ("solve", "verify_row", "verify_designs"),
    "hcmt.design.notes": ("NOTE_DISAGREEMENT", "weak_reasons", "verify_hint"),
}


def test_public_names_still_import_from_check():
    for module, names in MOVED.items():
        m = importlib.import_module(module)
        for name in names:
            assert getattr(check, name) is getattr(m, name), f"{module}.{name}"
    for name in ("Check", "check_designs", "predict_designs", "cost_check", "check_options"):
        assert callable(getattr(check, name))


def test_api_and_cli_names_resolve():
    import hcmt

    assert hcmt.predict_designs is check.predict_designs
