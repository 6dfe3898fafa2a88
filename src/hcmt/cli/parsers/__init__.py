"""Every command's arguments (``configure_NAME(parser)``) and its first checks (``check_NAME(args)``): light, no
torch, scipy, scikit-learn or matplotlib, so that a mistake in the command line is one line in a fraction of a
second, before the command's module (:data:`hcmt.cli.COMMANDS`) loads them. One module per command group, every
name importable from here: :mod:`~hcmt.cli.parsers.common` (counts, shared options and checks),
:mod:`~hcmt.cli.parsers.data` (generate, simulate, convert, info, hierarchy), :mod:`~hcmt.cli.parsers.train`
(train, rollout, evaluate, compare), :mod:`~hcmt.cli.parsers.design` (predict, sweep, models, surrogate) and
:mod:`~hcmt.cli.parsers.viz` (plot, export, demo).

Counts: every count option has its bound in its help, and a value outside it is refused in one line (one rule for
all, no silent capping): ``--threads`` and ``--workers`` at most this machine's cores, trajectories per split
:data:`hcmt.config.MAX_TRAJECTORIES`, designs :data:`hcmt.config.MAX_DESIGNS`, a batch :data:`hcmt.config.MAX_BATCH`.
"""
from __future__ import annotations

from hcmt.cli.parsers.common import (
    MAX_FPS,
    MAX_LEVELS,
    MAX_RESTARTS,
    MAX_STEPS,
    MAX_STRIDE,
    Once,
    batch_arg,
    check_folder,
    check_run,
    check_split,
    compile_arg,
    cores,
    cores_count,
    count,
    model_arg,
    readout_arg,
    same_as,
    span,
    surrogate_args,
    threads_arg,
    verify_arg,
)
from hcmt.cli.parsers.data import (
    check_convert,
    check_generate,
    check_hierarchy,
    check_info,
    check_simulate,
    configure_convert,
    configure_generate,
    configure_hierarchy,
    configure_info,
    configure_simulate,
    parse_families,
    plate_settings_of_args,
    range_overrides,
    settings_of_args,
    simulate_inputs,
)
from hcmt.cli.parsers.design import (
    check_options,
    check_predict,
    check_surrogate,
    check_sweep,
    configure_models,
    configure_predict,
    configure_surrogate,
    configure_sweep,
    take_model,
)
from hcmt.cli.parsers.train import (
    check_compare,
    check_evaluate,
    check_rollout,
    check_train,
    configure_compare,
    configure_evaluate,
    configure_rollout,
    configure_train,
)
from hcmt.cli.parsers.viz import (
    PICTURES,
    check_demo,
    check_export,
    check_plot,
    configure_demo,
    configure_export,
    configure_plot,
    frames_of,
    pictures_of,
)

__all__ = [
    "MAX_FPS", "MAX_LEVELS", "MAX_RESTARTS", "MAX_STEPS", "MAX_STRIDE", "Once", "PICTURES", "batch_arg",
    "check_compare", "check_convert", "check_demo", "check_evaluate", "check_export", "check_folder", "check_generate",
    "check_hierarchy", "check_info", "check_options", "check_plot", "check_predict", "check_rollout", "check_run",
    "check_simulate", "check_split", "check_surrogate", "check_sweep", "check_train", "compile_arg",
    "configure_compare", "configure_convert", "configure_demo", "configure_evaluate", "configure_export",
    "configure_generate", "configure_hierarchy", "configure_info", "configure_models", "configure_plot",
    "configure_predict", "configure_rollout", "configure_simulate", "configure_surrogate", "configure_sweep",
    "configure_train", "cores", "cores_count", "count", "frames_of", "model_arg", "parse_families", "pictures_of",
    "plate_settings_of_args", "range_overrides", "readout_arg", "same_as", "settings_of_args", "simulate_inputs",
    "span", "surrogate_args", "take_model", "threads_arg", "verify_arg",
]
