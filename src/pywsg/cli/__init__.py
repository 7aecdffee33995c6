"""The ``wsg`` command line."""
