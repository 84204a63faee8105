"""Assembly of runs from a config: batch -> engine -> tidy frame."""
