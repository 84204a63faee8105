"""The one batched fixed-step simulation engine and its streaming recorders."""
