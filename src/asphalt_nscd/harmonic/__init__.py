"""harmonic subpackage (see asphalt_nscd docstring)."""
