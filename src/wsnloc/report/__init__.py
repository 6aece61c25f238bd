"""Report building: figures (matplotlib, embedded as PNG) and HTML rendering (jinja2)."""
