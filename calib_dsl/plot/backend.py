"""matplotlib, when installed: a figure, and saving it in the format its file name says."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from calib_dsl.frontend.diagnostics import CalError

FORMATS = {".png": "png", ".svg": "svg", ".pdf": "pdf"}
INSTALL = "pip install calibc[plot]"
DPI = 100  # the PNGs stay small enough to commit (docs/figures/)


def file_format(path: str | Path) -> str:
    """png, svg or pdf, by the file's extension; else a user error."""
    suffix = Path(path).suffix.lower()
    if suffix not in FORMATS:
        raise CalError(f"cannot plot to '{path}': the file name must end in "
                       f"{', '.join(FORMATS)} (the format is chosen by the extension)")
    return FORMATS[suffix]


def require() -> None:
    """A user error, with how to install it, when matplotlib is missing."""
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise CalError(f"plotting needs matplotlib, which is not installed: {INSTALL}") from None


def new_figure(width: float, height: float) -> Any:
    """A figure on the Agg canvas (the object API: pyplot's global state is never touched)."""
    require()
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), layout="constrained", dpi=DPI)
    FigureCanvasAgg(fig)
    return fig


def save(fig: Any, path: str | Path) -> None:
    fmt = file_format(path)
    try:
        fig.savefig(path, format=fmt, dpi=DPI)
    except OSError as err:
        raise CalError(f"cannot write '{path}': {err.strerror or err}") from None
