"""The table of models, filled by the models themselves: each model class declares its name, label, settings and
whether it has attention with :func:`register`, and lists its attention taps (:meth:`Simulator.attention_taps`), so
adding a model touches its own module, the import in :mod:`hcmt.models` and :data:`hcmt.config.MODELS` only
(docs/extending.md). Light: no torch import, so the table can be read without building anything."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class ModelInfo:
    """What the rest of hcmt needs to know of a model without building it."""

    label: str  # the display label everywhere (tables, legends, titles)
    needs_hierarchy: bool  # HCMT: the mesh hierarchy (unless an ablation drops it)
    has_attention: bool  # has attention maps (hcmt.models.attention.recording, through the model's taps)
    settings: tuple[str, ...]  # the ModelConfig keys it is built from (its constructor arguments besides widths)
    builder: type | None = field(default=None, compare=False)  # the class: builder(node_in, ..., **arguments)
    extra: tuple[str, ...] = ()  # keyword arguments of the builder that are no ModelConfig key (HCMT's lpe_k)

    @property
    def arguments(self) -> tuple[str, ...]:
        """The keyword arguments :func:`hcmt.models.build_model` passes to :attr:`builder`."""
        return self.settings + self.extra


#: name -> :class:`ModelInfo`, in registration order (the order of the imports in :mod:`hcmt.models`)
REGISTRY: dict[str, ModelInfo] = {}


def register(
    name: str,
    label: str,
    *,
    settings: tuple[str, ...],
    needs_hierarchy: bool = False,
    has_attention: bool = False,
    extra: tuple[str, ...] = (),
):
    """Class decorator: enter the model under ``name`` (lower case, as ``model.name`` in a config and run.yaml's
    ``model.name``) with its builder, the class itself; a name registered twice is a bug."""

    def decorate(cls):
        if name in REGISTRY:
            raise RuntimeError(f"model {name!r} is registered twice")
        REGISTRY[name] = ModelInfo(label, needs_hierarchy, has_attention, tuple(settings), cls, tuple(extra))
        cls.model_name = name
        return cls

    return decorate
