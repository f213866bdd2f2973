"""Renderers: pictures of chunks (and, later, tool paths and simulations). Thin and optional."""
