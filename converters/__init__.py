"""Real multi-robot data to pose graphs: one reader module per source, the registry, the builder.

Installed as ``studio.converters`` (layer 3: imports the core and the formats).
"""
