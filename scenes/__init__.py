"""raster-oracle: scenes."""
