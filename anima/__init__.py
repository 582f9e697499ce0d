"""anima: monocular video and speech to 3D avatar animation, and back to video."""

__version__ = "0.1.0"
