"""User-facing errors. The CLI prints their message (no traceback) and exits with ``exit_code``."""


class AnimaError(Exception):
    exit_code = 1


class AssetNotFound(AnimaError):
    exit_code = 3


class InputError(AnimaError):
    """Bad user input: missing/corrupt file, no face, unsupported format."""

    exit_code = 2


class SchemaError(AnimaError):
    """An artifact of an unknown or incompatible schema version."""

    exit_code = 4
