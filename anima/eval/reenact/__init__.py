"""``anima eval reenact``: seed 001's self-re-enactment protocol (:mod:`.run`), its metrics (:mod:`.metrics`)
and LPIPS (:mod:`.lpips`)."""
