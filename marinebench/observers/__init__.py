"""State observers. Each kind has a pydantic tuning model and a batched implementation."""
