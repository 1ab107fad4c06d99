"""hrc-cosim common library: wire contract, bus helpers, scenario model, command-line interface."""

__version__ = "0.1.0"
