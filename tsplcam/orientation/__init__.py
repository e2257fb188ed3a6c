"""Orientation stage: tool axes that keep shank and holder off the part, smoothed along the path."""
