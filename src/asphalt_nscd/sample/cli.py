"""Subcommands of the sample step (registered by asphalt_nscd.cli)."""


def register(subparsers) -> None:
    """Add this step's subcommands to the asphalt-nscd parser."""
