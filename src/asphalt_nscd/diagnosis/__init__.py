"""diagnosis subpackage (see asphalt_nscd docstring)."""
