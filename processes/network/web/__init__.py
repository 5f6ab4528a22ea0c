"""The browser's side: the bridge from a gateway's session to browsers (bridge), a browser's
player session (player), a recorded match as one offline page (replay), and the page itself
(static/: the HTML, the app, the wire decoder, vendored three.js)."""
from pathlib import Path

STATIC = Path(__file__).with_name("static")  # the page, its scripts and vendor/three.js

__all__ = ["STATIC"]
