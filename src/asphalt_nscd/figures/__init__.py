"""figures subpackage (see asphalt_nscd docstring)."""
