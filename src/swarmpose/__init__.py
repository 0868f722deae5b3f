"""swarmpose."""
