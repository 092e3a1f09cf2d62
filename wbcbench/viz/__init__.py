"""Seeing runs: MP4 video with overlays and key-frame strips from a run directory (render.py)."""
