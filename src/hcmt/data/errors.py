"""The one exception type for bad input data."""


class DatasetError(ValueError):
    """Bad input: names the file, trajectory and field at fault and what was expected."""

    def __init__(self, message: str, *, file=None, trajectory=None, field=None):
        where = ", ".join(
            f"{k} {v!s}" for k, v in (("file", file), ("trajectory", trajectory), ("field", field)) if v is not None
        )
        super().__init__(f"{where}: {message}" if where else message)
        self.file, self.trajectory, self.field = file, trajectory, field
