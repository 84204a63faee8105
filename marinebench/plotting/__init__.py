"""Matplotlib figures (Agg backend; no display needed)."""
