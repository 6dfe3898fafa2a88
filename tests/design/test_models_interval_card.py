"""`hcmt models` reports the mesh model's own interval: its calibrated cells, the held-out designs behind each and
the coverage measured on other seeds, from the calibration file beside the model."""

from hcmt.cli.design import interval_card, interval_lines
from hcmt.design.model_interval import ANSWERS, Calibration, Cell


class _Run:
    def __init__(self, folder):
        self.source = str(folder)
        self.folder = type("F", (), {"path": folder})()


def test_models_lines_name_each_cell_its_designs_and_measured_coverage(tmp_path):
    cells = {
        "inside": Cell(60, {a: 0.0 for a in ANSWERS}, {a: 0.05 for a in ANSWERS}, 0.1),
        "thickness+:0.2": Cell(24, {a: 0.1 for a in ANSWERS}, {a: 0.08 for a in ANSWERS}, 0.2),
    }
    measured = {
        "by_cell": {
            "inside": {
                "designs": 120,
                "peak_plate_stress_mpa": 0.958,
                "max_deflection_mm": 0.933,
                "plate_stress_history_mpa": 0.9,
                "median_rel_width_peak": 0.11,
            }
        }
    }
    Calibration("run", 0.95, cells, {}, measured).save(tmp_path / "interval.json")
    card = interval_card(_Run(tmp_path))
    assert card["cells"] == {"inside": 60, "thickness+:0.2": 24}
    text = interval_lines(card)
    assert "inside" in text and "60 designs; covers 96 / 93 / 90 % of 120, width 11 %" in text
    assert "thickness+:0.2" in text and "24 designs; not measured" in text
    assert "none calibrated" in interval_lines(interval_card(_Run(tmp_path / "elsewhere")))
