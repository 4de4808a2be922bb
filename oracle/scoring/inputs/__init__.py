"""oracle.scoring.inputs: what is scored: candidate files, their layouts, manifests, folder cases
and frame files."""
