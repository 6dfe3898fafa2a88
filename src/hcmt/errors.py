"""The library's exceptions for bad input: the ground floor, below everything that raises them.

An :class:`InputError` is a mistake its caller can fix (a value, a file, a design); it names the parameter at fault
(``param``), so that ``hcmt`` can print the command-line flag of that parameter instead (``batch`` -> ``--batch``)
and exit 2 with one line. Any other exception is a bug and keeps its traceback.
"""

from __future__ import annotations

import importlib
import importlib.util


class InputError(ValueError):
    """Bad input, one line: ``param message`` (``batch must be >= 1, got 0``; ``param`` is the Python API's
    parameter name, or None when the message names its file or key itself). A ``ValueError``, so
    ``except ValueError`` still catches it."""

    def __init__(self, message: str, *, param: str | None = None):
        self.param, self.detail = param, message
        super().__init__(f"{param} {message}" if param else message)

    def worded(self, name: str | None) -> str:
        """The message with the parameter called ``name`` (a flag: ``--batch must be >= 1, got 0``) instead of
        its API name; unchanged for None."""
        return f"{name} {self.detail}" if name and self.param else str(self)


class RolloutError(RuntimeError):
    """A learned rollout whose predicted state became non-finite (the model diverged on this input): one line
    naming the trajectory and the step, no traceback; not a bug of hcmt's."""


class DatasetError(InputError):
    """Bad input data: names the file, trajectory and field at fault and what was expected."""

    def __init__(self, message: str, *, file=None, trajectory=None, field=None):
        where = ", ".join(
            f"{k} {v!s}" for k, v in (("file", file), ("trajectory", trajectory), ("field", field)) if v is not None
        )
        super().__init__(f"{where}: {message}" if where else message)
        self.file, self.trajectory, self.field = file, trajectory, field


class MissingExtra(InputError, ImportError):
    """An optional dependency is not installed: one line naming the extra that installs it
    (``matplotlib is not installed; pip install 'hcmt[viz]'``). An :class:`InputError` (the command line prints it in
    one line) and an ``ImportError``."""


def _missing(module: str, extra: str) -> MissingExtra:
    top = module.split(".")[0]
    return MissingExtra(f"{top} is not installed (the {extra} extra); pip install 'hcmt[{extra}]'")


def require(module: str, extra: str):
    """Import the optional dependency ``module`` (installed by ``pip install 'hcmt[EXTRA]'``) and return it, or
    raise :class:`MissingExtra` naming the extra."""
    try:
        return importlib.import_module(module)
    except ImportError:
        raise _missing(module, extra) from None


def missing_extra(extra: str, *modules: str) -> str | None:
    """The one-line message of :class:`MissingExtra` for the first of ``modules`` that cannot be imported, or None
    when all can; imports nothing."""
    for module in modules:
        try:
            found = importlib.util.find_spec(module) is not None
        except (ImportError, ValueError):  # a parent package missing, or a module set to None in sys.modules
            found = False
        if not found:
            return str(_missing(module, extra))
    return None


def require_installed(extra: str, *modules: str) -> None:
    """Fail with :class:`MissingExtra` unless every one of ``modules`` can be imported; imports nothing."""
    message = missing_extra(extra, *modules)
    if message is not None:
        raise MissingExtra(message)


def clip(text, limit: int = 60) -> str:
    """A value a user gave, shortened for a one-line message: at most ``limit`` characters, the cut marked
    with "…" (a 5,000-character design name is echoed as its first 59 characters and "…")."""
    text = str(text)
    return text if len(text) <= limit else text[: limit - 1] + "…"
