"""Raw-log parsers (one module per format) and the canonical Parquet tables they produce."""
