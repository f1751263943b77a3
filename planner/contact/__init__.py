"""Reachability-based contact planning: root paths, contact states and sequences, one-step mode."""

from planner.contact.state import ContactState, LimbContact

__all__ = ["ContactState", "LimbContact"]
