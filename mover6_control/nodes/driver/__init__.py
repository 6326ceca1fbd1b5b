"""The driver node of the real Mover6 and its parts."""
