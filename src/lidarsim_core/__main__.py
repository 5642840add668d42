"""``python -m lidarsim_core`` runs the ``lidarsim`` command line."""

from .cli import main

main()
