"""Measurement noise models."""
