"""The API's resources, one module each; every handler parses, calls the service, answers."""
