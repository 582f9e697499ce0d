"""Readers and writers: assets, video/audio, artifacts (one reader and one writer each), exports."""
