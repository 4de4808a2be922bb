"""raster-oracle: raster_models."""
