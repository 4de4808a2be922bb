"""Reference geometry computed beside the ray tracer: exact (analytic) pixel coverage and the
pixel-area integrals it uses, film motion vectors, and FTIZB's 32 tangent-plane points."""
