"""Scene geometry beside the ray tracer: mesh generators (:mod:`.meshes`) and the tessellation
of a scene's shapes (:mod:`.tessellation`), exact (analytic) pixel coverage and the pixel-area
integrals it uses, film motion vectors, and FTIZB's 32 tangent-plane points."""
