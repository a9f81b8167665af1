"""The Manager's Editor: designs, the palette, and the export, follower and
fixed tables."""
