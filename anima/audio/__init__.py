"""Speech features aligned to motion frames (seed 004 §4.3.3)."""
