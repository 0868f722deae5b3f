"""``python -m swarmpose``: the same as the ``swarmpose`` command."""

from swarmpose.cli.app import main

main()
