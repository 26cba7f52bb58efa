"""Training, one trainer per model (offline; nothing at run time imports this package)."""
