"""PickStop: where a mobile manipulator should stop to pick every part, and the route between."""

__version__ = "0.1.0"
