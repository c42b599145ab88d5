"""Scene files and capture specs: YAML and mappings turned into validated, immutable objects."""
