"""File formats: one module per format, each with a reader and a writer."""
