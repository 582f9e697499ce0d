"""Metrics as plain functions (docstrings name the protocol) and the runners that print JSON."""
