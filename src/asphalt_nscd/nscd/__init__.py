"""nscd subpackage (see asphalt_nscd docstring)."""
