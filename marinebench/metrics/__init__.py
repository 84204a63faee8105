"""Statistics over Monte-Carlo runs."""
