"""raster-oracle: oracle."""
