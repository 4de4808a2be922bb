"""raster-oracle: metrics."""
