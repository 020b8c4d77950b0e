"""Shared figure finishing for every PNG the commands write (matplotlib, Agg backend)."""
from __future__ import annotations

from pathlib import Path

__all__ = ["save_figure"]


def save_figure(fig, path, axes=(), dpi: int = 110) -> Path:
    """Grid on ``axes``, tight layout, write ``path`` as PNG, close the figure; return the path."""
    import matplotlib.pyplot as plt
    for a in axes:
        a.grid(alpha=0.3)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path
