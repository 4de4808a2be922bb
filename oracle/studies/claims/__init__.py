"""oracle.studies.claims."""
