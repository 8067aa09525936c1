"""hconv's version, in one place: the package's metadata (pyproject.toml reads it from here),
``hconv --version``, the manifests and Parquet metadata hconv writes, and a cluster's check that
every worker runs the same hconv. A module of the bottom layer, so that every layer may ask it."""

__version__ = "0.1.0"
