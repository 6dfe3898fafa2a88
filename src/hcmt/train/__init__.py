"""Training, rollout, evaluation and the design check. The package itself is callable, so that ``hcmt.train`` is
both this subpackage and the API function ``hcmt.train(config, data, model, out, **options)`` (importing a
subpackage binds its name on the parent package; a callable module keeps the two the same object)."""
import sys
import types


def train(config, data, model: str, out, **options):
    """Train ``model`` (``hcmt``, ``mgn``, ``gt``) on the native dataset ``data`` into the run folder ``out``.
    ``config`` is a config dict, a built-in config name or a YAML path; ``options``: ``ablation``, ``seed``,
    ``resume``, ``device``, ``progress``, and ``overrides`` (a list of ``section.key=value``). Returns the training
    summary; :meth:`hcmt.Run.load` (``out``) gives the trained model."""
    from hcmt.train.config import load_config
    from hcmt.train.trainer import train as run_training

    overrides = options.pop("overrides", None)
    cfg = config if isinstance(config, dict) else load_config(str(config), overrides)
    return run_training(cfg, data, model, out, **options)


class _CallableModule(types.ModuleType):
    def __call__(self, *args, **kwargs):
        return train(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule
