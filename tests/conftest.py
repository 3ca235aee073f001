"""Shared test set-up: kernel cache in the user cache dir unless DEMSCALE_CACHE_DIR is set."""
