"""pathlight renders split over a Dask cluster (see `farm.render`)."""

from .farm import ranges, render, render_range

__all__ = ["ranges", "render", "render_range"]
