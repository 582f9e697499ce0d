"""Thin command-line entry points: parse, build a config, call the API."""
