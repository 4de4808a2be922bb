"""oracle.studies.extremes."""
