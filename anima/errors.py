"""User-facing errors. The CLI prints their message as one line (no traceback) and exits with ``exit_code``:
2 bad input, 3 missing asset, 4 incompatible or unsafe file (schema, checkpoint)."""


class AnimaError(Exception):
    exit_code = 1


class AssetNotFound(AnimaError):
    exit_code = 3


class InputError(AnimaError):
    """Bad user input: missing/corrupt file, no face, unsupported format, out-of-range option."""

    exit_code = 2


class SchemaError(AnimaError):
    """An artifact of an unknown or incompatible schema version."""

    exit_code = 4


class CheckpointError(SchemaError):
    """A checkpoint that cannot be loaded: not a checkpoint, unsafe (a pickle that would run code), another
    model kind or version, or weights that do not fit its config."""
