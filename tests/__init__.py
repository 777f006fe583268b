"""simbench's tests, a folder a stage as the package's (tests/<stage>/), shared fixtures in conftest."""
