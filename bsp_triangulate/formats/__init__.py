"""Input and output formats: WKB in, mesh files and number text out."""
