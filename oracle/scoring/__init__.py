"""oracle.scoring."""
