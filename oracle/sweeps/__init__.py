"""oracle.sweeps."""
