"""raster-oracle: reports."""
