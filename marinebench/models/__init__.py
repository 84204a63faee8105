"""Vessel models with batched dynamics ``f(x, tau)`` over runs ``(B, n)``."""
