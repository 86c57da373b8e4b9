"""Notebook helpers: DataFrames from messages (:mod:`.frames`), live plots and a live camera
view for Jupyter (:mod:`.live`), and example notebooks (``*.ipynb`` next to this file)."""

from pathlib import Path

NOTEBOOKS = Path(__file__).resolve().parent


def example_notebooks() -> list[Path]:
    """The example notebooks shipped with the package."""
    return sorted(NOTEBOOKS.glob("*.ipynb"))
