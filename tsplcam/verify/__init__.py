"""Verify: measures what the other stages made (scallop, gouge, collisions, smoothness, time).
May read any stage; no stage reads it."""
