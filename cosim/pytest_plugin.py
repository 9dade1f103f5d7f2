"""pytest plugin (``pytest11`` entry point): regression fixtures for co-simulation scenarios."""
