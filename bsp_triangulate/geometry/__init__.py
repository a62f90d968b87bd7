"""Exact predicates, rings, bridges, validity and the spatial indexes."""
