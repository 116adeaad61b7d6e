"""One module per ``fisheye-des`` sub-command; each defines ``register(app)``."""
