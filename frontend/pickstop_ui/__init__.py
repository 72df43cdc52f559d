"""The PickStop 3D planner (viser), a client of the REST API."""
