"""hconv.charts: the speed-against-accuracy chart's labels."""

from __future__ import annotations

import numpy as np
from matplotlib.text import Text

from hconv import charts


def test_place_labels_clustered_points_each_label_readable_and_by_its_point():
    """Points closer in speed than their labels are wide (the float32 methods of a bench run
    sit within 30 % of each other at one error), two of them in the frame's corner under the
    title: every label stays inside the axes, covers no other label and no point, and either
    starts nearest its own point or has a line to it."""
    plt = charts._pyplot()
    fig, ax = plt.subplots(figsize=(12, 7.5), constrained_layout=True)
    speeds = np.array([0.85e6, 0.86e6, 1.26e6, 1.55e6, 1.62e6, 1.70e6, 1.9e6, 1.95e6, 2.0e6])
    errs = np.array([1.5, 1.5, 4e-4, 4.5e-4, 5e-4, 6e-4, 1.0, 1.0, 1.0])
    ax.scatter(speeds, errs)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlim(7e5, 5e7)
    ax.set_ylim(1e-18, 10)
    ax.set_title("a title of two lines\nthat no label may cover")
    labels = [(x, y, f"method number {k} f32", 1) for k, (x, y) in enumerate(zip(speeds, errs))]
    charts._place_labels(fig, ax, labels)
    renderer = fig.canvas.get_renderer()
    frame = ax.get_window_extent(renderer)
    points = ax.transData.transform(np.column_stack([speeds, errs]))
    boxes = []
    for k, label in enumerate(ax.texts):
        box = Text.get_window_extent(label, renderer)
        boxes.append(box)
        assert frame.x0 <= box.x0 and box.x1 <= frame.x1 and frame.y0 <= box.y0 and box.y1 <= frame.y1
        assert not any(box.x0 < px < box.x1 and box.y0 < py < box.y1 for px, py in points)
        if label.arrow_patch is None:
            start = (box.x0 if label.get_ha() == "left" else box.x1, (box.y0 + box.y1) / 2)
            assert np.argmin(np.hypot(*(points - start).T)) == k
    assert len(boxes) == len(labels)
    assert not any(a.overlaps(b) for i, a in enumerate(boxes) for b in boxes[i + 1 :])
    plt.close(fig)
