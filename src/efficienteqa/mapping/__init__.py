"""Mapping: pure arrays-in, arrays-out modules (grids, TSDF, 2-D maps, values)."""
