"""Gecko planner: scenes, characters and their offline data, and the planners that use them.

Depends on ``trajectory`` (maths); never on ``service``.
"""
