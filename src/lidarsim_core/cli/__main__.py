"""``python -m lidarsim_core.cli`` runs the ``lidarsim`` command line."""

from .main import main

main()
