"""sample subpackage (see asphalt_nscd docstring)."""
