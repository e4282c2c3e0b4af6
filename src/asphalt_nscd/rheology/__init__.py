"""rheology subpackage (see asphalt_nscd docstring)."""
