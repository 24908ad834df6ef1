"""Package data of :mod:`analysis`: the paper's published tables (see ``SOURCES.md``)."""
