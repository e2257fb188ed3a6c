"""Plan stage: the processing list (patch order, start/finish corners, crossfeed)."""
