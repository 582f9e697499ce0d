"""Rasterizer, mesh and overlay renders, side-by-side videos."""
