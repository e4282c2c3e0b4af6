"""lab subpackage (see asphalt_nscd docstring)."""
