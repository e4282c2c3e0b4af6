"""campaign subpackage (see asphalt_nscd docstring)."""
