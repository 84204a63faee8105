"""Writing results: atomic directories, manifest, markdown tables."""
