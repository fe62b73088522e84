"""Everything Rerun: entity paths and timelines, one ``log_<kind>`` module per kind of data, checks, viewer.

Layer 4: imports the core and the formats; pipelines import it, never the other way.
"""
