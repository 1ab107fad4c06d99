"""The ``hrc`` command-line interface."""
