"""Live Link Face UDP packets: the layout Epic's Live Link Face iPhone app sends and Unreal's Live Link plugin
(``LiveLinkFace`` / Apple ARKit face source) reads, one packet per frame:

==========  ==========================================================================================
bytes       what
==========  ==========================================================================================
4           packet version, little-endian uint32 (6)
37          device id: ``$`` and a 36-character UUID, UTF-8
4           subject name length, big-endian int32, then the name (UTF-8)
8           frame time: frame number (big-endian int32) and its fraction (big-endian float32)
8           frame rate: numerator and denominator (big-endian int32 each)
1           value count (61)
244         61 big-endian float32: the 52 ARKit blendshapes, head yaw, pitch, roll, left eye yaw, pitch,
            roll, right eye yaw, pitch, roll (the order of ``anima.io.arkit.LIVE_LINK_COLUMNS`` +
            ``HEAD_COLUMNS``: the app's CSV order)
==========  ==========================================================================================

Pure packing and unpacking; the sender is :mod:`anima.export.livelink`."""

from __future__ import annotations

import struct

import numpy as np

VERSION = 6
N_VALUES = 61
_ID_LEN = 37


def pack(device_id: str, subject: str, frame: int, sub_frame: float, fps: int, values: np.ndarray) -> bytes:
    """One packet. ``device_id``: a UUID (``$`` is prefixed when missing); ``values``: the 61 floats."""
    did = device_id if device_id.startswith("$") else "$" + device_id
    did_b = did.encode("utf-8")
    if len(did_b) != _ID_LEN:
        raise ValueError(f"a Live Link device id is '$' and a 36-character UUID, not {device_id!r}")
    name = subject.encode("utf-8")
    v = np.asarray(values, np.float64).ravel()
    if v.size != N_VALUES or not np.isfinite(v).all():
        raise ValueError(f"a Live Link Face packet carries {N_VALUES} finite values")
    return (
        struct.pack("<I", VERSION)
        + did_b
        + struct.pack("!i", len(name))
        + name
        + struct.pack("!if", int(frame), float(sub_frame))
        + struct.pack("!ii", int(fps), 1)
        + struct.pack("!B", N_VALUES)
        + struct.pack(f"!{N_VALUES}f", *v)
    )


def unpack(data: bytes) -> dict:
    """A packet's fields: ``version``, ``device_id``, ``subject``, ``frame``, ``sub_frame``, ``fps``,
    ``denominator``, ``values [61]``. ValueError for what is not one."""
    try:
        version = struct.unpack("<I", data[:4])[0]
        did = data[4 : 4 + _ID_LEN].decode("utf-8")
        n = struct.unpack("!i", data[4 + _ID_LEN : 8 + _ID_LEN])[0]
        p = 8 + _ID_LEN
        if not 0 <= n <= 1024:
            raise ValueError("subject name length")
        subject = data[p : p + n].decode("utf-8")
        p += n
        frame, sub = struct.unpack("!if", data[p : p + 8])
        fps, den = struct.unpack("!ii", data[p + 8 : p + 16])
        count = data[p + 16]
        values = np.array(struct.unpack(f"!{count}f", data[p + 17 : p + 17 + 4 * count]))
    except (struct.error, IndexError, UnicodeDecodeError) as e:
        raise ValueError(f"not a Live Link Face packet ({e})") from None
    if count != N_VALUES or len(data) != p + 17 + 4 * count:
        raise ValueError(f"not a Live Link Face packet ({count} values, {len(data)} bytes)")
    return {"version": version, "device_id": did, "subject": subject, "frame": frame, "sub_frame": sub,
            "fps": fps, "denominator": den, "values": values}  # fmt: skip
