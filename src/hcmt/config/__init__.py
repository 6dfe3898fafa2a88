"""hcmt's configs, one module per job: :mod:`~hcmt.config.choices` (the values each config key and option may take,
declared once), :mod:`~hcmt.config.yamlread` (YAML without duplicate keys, command-line values),
:mod:`~hcmt.config.sections` (the schema's sections and defaults), :mod:`~hcmt.config.schema` (its checks,
overrides and the complete :class:`Config`), :mod:`~hcmt.config.loading` (built-in configs by name, files, ``base``
chains) and :mod:`~hcmt.config.threads` (torch's CPU threads). Every public name is importable from here.

Configs are YAML: built-in ones by name (``src/hcmt/configs/NAME.yaml``, also reachable as ``configs/``), or a
file path. A config may name a ``base`` config whose values it overrides: a built-in config's name, or a path read
from the folder of the file naming it; a chain that returns to a file is refused. Files are read as YAML 1.1 with
YAML 1.2's floats (``lr: 1e-3`` is a number) and without duplicate keys (refused, both lines named). Any key can be
overridden from the command line as ``section.key=value`` (the value is parsed as YAML: ``train.lr=3e-4``,
``model.levels=4``). Light: no torch (the command's parsers read it before torch loads)."""

from __future__ import annotations

from hcmt.config.choices import (
    ABLATION_ALIASES,
    ABLATIONS,
    ATTENTION_MODES,
    COMPILE_MODES,
    CONTACT_PAIR_NAMES,
    DATASET_NAMES,
    INFERENCE_COMPILE_MODES,
    INIT_NORMALIZERS,
    LOSS_DENOMINATORS,
    MAX_BATCH,
    MAX_DESIGNS,
    MAX_TRAJECTORIES,
    MODELS,
    NO_REMESH,
    NOISE_NODES,
    NORMALIZER_WARMUPS,
    POLICY_NAMES,
    PRECISIONS,
    STRESS_FIELDS,
    TARGET_NAMES,
    TORCH_COMPILE_MODES,
)
from hcmt.config.loading import (
    CONFIG_DIR,
    PRETRAINED_DIR,
    as_config,
    available_pretrained,
    builtin_configs,
    check_same_dataset,
    load_config,
    set_in,
)
from hcmt.config.schema import (
    SCHEMA,
    TOP,
    Config,
    Spec,
    apply_overrides,
    check_schema,
    current_model_args,
    override_list,
)
from hcmt.config.sections import SECTIONS, DataConfig, ModelConfig, TrainConfig
from hcmt.config.threads import auto_threads, default_threads, machine_cores, set_threads
from hcmt.config.yamlread import load_yaml, merge, parse_value

#: the package version (``hcmt --version``, ``hcmt.__version__``; a literal: setuptools reads it without importing)
VERSION = "0.1.0"


def plural(n: int, word: str, many: str | None = None) -> str:
    """``1 trajectory``, ``2 trajectories``: a count with its noun (``many``: the plural when not ``word + s``)."""
    return f"{n} {word if n == 1 else (many or word + 's')}"


__all__ = [
    "ABLATIONS",
    "ABLATION_ALIASES",
    "ATTENTION_MODES",
    "COMPILE_MODES",
    "CONFIG_DIR",
    "CONTACT_PAIR_NAMES",
    "DATASET_NAMES",
    "INFERENCE_COMPILE_MODES",
    "INIT_NORMALIZERS",
    "LOSS_DENOMINATORS",
    "MAX_BATCH",
    "MAX_DESIGNS",
    "MAX_TRAJECTORIES",
    "MODELS",
    "NOISE_NODES",
    "NORMALIZER_WARMUPS",
    "NO_REMESH",
    "POLICY_NAMES",
    "PRECISIONS",
    "PRETRAINED_DIR",
    "SCHEMA",
    "SECTIONS",
    "STRESS_FIELDS",
    "TARGET_NAMES",
    "TOP",
    "TORCH_COMPILE_MODES",
    "VERSION",
    "Config",
    "DataConfig",
    "ModelConfig",
    "Spec",
    "TrainConfig",
    "apply_overrides",
    "as_config",
    "auto_threads",
    "available_pretrained",
    "builtin_configs",
    "check_same_dataset",
    "check_schema",
    "current_model_args",
    "default_threads",
    "load_config",
    "load_yaml",
    "machine_cores",
    "merge",
    "override_list",
    "parse_value",
    "plural",
    "set_in",
    "set_threads",
]
