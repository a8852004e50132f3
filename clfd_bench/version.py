"""The package version, in a module of its own so lower layers (the execution fingerprint)
read it without importing the package's top level."""

__all__ = ["__version__"]

__version__ = "0.1.0"
