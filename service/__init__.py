"""Gecko HTTP service: schemas, routes, registry of scenes and characters, workers."""

__version__ = "0.1.0"
