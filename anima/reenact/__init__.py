"""Re-enactment of an actor's lower-face expression on a target person's video (seed 001)."""
