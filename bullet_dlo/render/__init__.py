"""Headless rendering: renderers, cameras, the cable tube, video and force plots."""
