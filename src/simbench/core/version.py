"""simbench's version: a leaf module, so that what writes it (reports, pages) need not import the package."""

__version__ = "0.1.0"
