"""``python -m swarmpose``: the same as the ``swarmpose`` command."""

from swarmpose.cli.app import main

if __name__ == "__main__":
    main()
