"""File formats: CSV records and model files."""
