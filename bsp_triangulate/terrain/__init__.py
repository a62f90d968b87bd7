"""Elevation helpers: raster sampling, planar snapping, densification."""
