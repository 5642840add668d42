"""The foundation every other layer stands on: errors, reading input files, the resource
budget, validation messages, the component base class, threads, atomic outputs and the
overwrite policy, OS-error wording, signals and optional dependencies.

Nothing here imports any other part of lidarsim (an import-linter contract holds it).
"""
