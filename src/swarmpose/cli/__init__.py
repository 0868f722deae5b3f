"""Command-line interface (``swarmpose``). Each command group lives in its own module."""
