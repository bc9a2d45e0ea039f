"""pathlight renders split over a Dask cluster (see `farm.render` and `farm.eval_references`)."""

from .farm import eval_references, ranges, render, render_range

__all__ = ["eval_references", "ranges", "render", "render_range"]
