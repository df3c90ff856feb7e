"""The package version, in a module of its own so that any layer may name it without importing
the package's lazy ``__init__`` (which reaches the pipeline)."""

__version__ = "0.1.0"
