"""Configuration: a config file and its routes (`bridge`), what the way back may command
(`commands`), the mapping tables, the YAML reader that names file:line, the registries that
find transports and translators by name, and where the shipped data lives."""
