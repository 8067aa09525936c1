"""hconv.charts: the speed-against-accuracy chart's labels."""

from __future__ import annotations

import numpy as np

from hconv import charts


def test_place_labels_clustered_points_no_label_covers_another_or_a_point():
    """Points closer in speed than their labels are wide (the float32 methods in a bench run sit
    within 30 % of each other at one error): every label lands where it covers no other label
    and no point."""
    plt = charts._pyplot()
    fig, ax = plt.subplots(figsize=(12, 7.5), constrained_layout=True)
    speeds = [1.26e6, 1.55e6, 1.62e6, 1.70e6, 1.9e6, 2.0e6]
    errs = [4e-4, 4.5e-4, 5e-4, 6e-4, 1.0, 1.0]
    ax.scatter(speeds, errs)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlim(7e5, 5e7)
    ax.set_ylim(1e-18, 10)
    charts._place_labels(fig, ax, [(x, y, f"method {k} f32", 1) for k, (x, y) in enumerate(zip(speeds, errs))])
    renderer = fig.canvas.get_renderer()
    boxes = [t.get_window_extent(renderer) for t in ax.texts]
    assert len(boxes) == len(speeds)
    for i, a in enumerate(boxes):
        assert not any(a.overlaps(b) for b in boxes[i + 1 :])
        for px, py in ax.transData.transform(np.column_stack([speeds, errs])):
            assert not (a.x0 < px < a.x1 and a.y0 < py < a.y1)
    plt.close(fig)
