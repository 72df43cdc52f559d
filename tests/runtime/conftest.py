"""The service's fixtures (a service over the session's database) for the runtime's tests."""

from tests.api.conftest import AUTH, KEY, api_settings, client  # noqa: F401
