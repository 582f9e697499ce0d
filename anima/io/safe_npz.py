"""Reading object arrays (pickled dicts of arrays, as VideoPose3D's HumanEva files are) without running code:
the pickle inside the ``.npy`` member is read by an unpickler that knows numpy's array reconstruction and
nothing else, so numpy never has to be allowed to unpickle."""

from __future__ import annotations

import pickle
import zipfile
from pathlib import Path

import numpy as np

from anima.errors import InputError

_ALLOWED = {
    ("numpy.core.multiarray", "_reconstruct"),
    ("numpy._core.multiarray", "_reconstruct"),
    ("numpy", "ndarray"),
    ("numpy", "dtype"),
    ("numpy.core.multiarray", "scalar"),
    ("numpy._core.multiarray", "scalar"),
}


class _NumpyOnly(pickle.Unpickler):
    def find_class(self, module, name):
        if (module, name) in _ALLOWED:
            return super().find_class(module, name)
        raise pickle.UnpicklingError(f"refused: the file wants to load {module}.{name}")


def load_object_member(path: str | Path, key: str):
    """The Python object stored as ``key`` (an object array holding e.g. a dict) in the npz ``path``."""
    try:
        with zipfile.ZipFile(path) as z, z.open(f"{key}.npy") as fh:
            version = np.lib.format.read_magic(fh)
            shape, _, dtype = np.lib.format._read_array_header(fh, version)
            if dtype.hasobject:
                obj = _NumpyOnly(fh, encoding="latin1").load()
            else:
                obj = np.lib.format.read_array(fh, allow_pickle=False)
    except (OSError, KeyError, ValueError, zipfile.BadZipFile, pickle.UnpicklingError, EOFError) as e:
        raise InputError(f"{path}: cannot read {key!r} ({e})") from None
    return obj.item() if isinstance(obj, np.ndarray) and obj.shape == () else obj
