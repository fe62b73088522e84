"""Converters from real multi-robot data to pose graphs (one module per source format)."""
