"""The kollagen engine: a bit-exact numpy re-implementation of kollagen's generator (no I/O).

Installed as ``studio.generator`` (layer 1: imports the core only).
"""
