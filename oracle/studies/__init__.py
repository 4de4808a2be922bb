"""oracle.studies."""
