"""
Connected components of a graph given as its edges, in whole-array steps; numpy only.

Both the mesh cache's connected pieces (faces joined by a shared corner) and the
plane merge's facets (faces joined by a shared edge on one plane) are components.
"""

import numpy

__all__ = ['lowest_labels']


def lowest_labels(count: int, first: numpy.ndarray, second: numpy.ndarray) -> numpy.ndarray:
    """
    Return, for each of ``count`` nodes, the lowest node of its component (edges first-second).

    Whole-array steps (the interpreter lock released in each), not a loop
    over edges: every node points at the smallest node of its component found
    so far, each edge hooks the larger of its two ends' roots onto the
    smaller, then the pointers are followed to their roots; each round at
    least halves the components.
    """
    parent = numpy.arange(count)
    while True:
        a, b = parent[first], parent[second]
        apart = a != b
        if not apart.any():
            return parent
        low, high = numpy.minimum(a, b)[apart], numpy.maximum(a, b)[apart]
        numpy.minimum.at(parent, high, low)
        while True:  # to the roots
            grand = parent[parent]
            if numpy.array_equal(grand, parent):
                break
            parent = grand
