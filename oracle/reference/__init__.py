"""oracle.reference."""
