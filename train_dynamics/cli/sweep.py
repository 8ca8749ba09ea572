"""Placeholder."""


def add_parser(sub):
    """Add nothing yet."""
