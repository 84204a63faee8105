"""Tracking controllers (batched per DOF): RISE and saturated super-twisting RISE (S+RISE)."""
