"""``python -m lidarsim_core`` runs the ``lidarsim`` command line."""

from lidarsim_core.cli import main

main()
