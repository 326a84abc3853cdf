"""gap package."""
