"""The re-enactment's settings (light), so the command line builds its options from them."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class ReenactConfig:
    n: int = field(default=100, metadata={"range": (1, 100_000)})
    """Nearest target frames: the validation clip's choice with ``detail`` 1 (``python
    benchmarks/reenact_sharpness.py``: lowest LPIPS within the tLP bound; the seed's 100 too)."""
    a: float = field(default=0.9, metadata={"range": (1e-6, 1 - 1e-6)})
    """Weight fraction the n best carry (eq. 3.4; seed 0.9)."""
    smooth: int = field(default=5, metadata={"range": (0, 1000)})
    """Method 2 smoothing window T in frames on vertices and colours (eq. 3.5); 0 = method 1."""
    levels: int = 4  # Laplacian pyramid levels
    erode: float = 0.04  # mask erosion, fraction of the region's height
    blur: float = 0.10  # mask feather, fraction of the region's height
    map_expressions: bool = field(default=True, metadata={"flag": "--no-mapping"})
    """Identity mismatch: normalise the actor's expression statistics to the target's (off: --no-mapping)."""
    color_transfer: bool = field(default=True, metadata={"flag": "--no-color-transfer"})
    """Colour and lighting per frame: every database frame's colours moved to a common skin reference before
    the weighted median, the result moved to the output frame's own skin (off: --no-color-transfer)."""
    detail: float = field(default=1.0, metadata={"range": (0.0, 2.0)})
    """Mouth-interior detail: add this much of the highest-weight frame's high frequencies (teeth, lip line)
    to the median there (0 = the seed's median alone; 1 was chosen on a validation clip, Obama clip 2)."""
    hold_frames: int = 8  # actor face lost: hold the last expression this many frames ...
    fade_frames: int = 8  # ... then fade to the target's own frame over these
