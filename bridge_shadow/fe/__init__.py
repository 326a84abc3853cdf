"""fe package."""
