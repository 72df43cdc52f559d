"""The REST service: FastAPI under /api/v1."""
