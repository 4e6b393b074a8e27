"""Meagher's back-to-front octree display as a recursion, face by face.

The oracle of :mod:`voxrender._render.octree_btf`.  It takes nothing from the production renderers but the
region octree itself: the view plane normal, the visible faces, the order of the children and the
scan-conversion of each face (:mod:`.geometry`, every pixel whose ray meets the closed square, at the depth
where it meets it) are its own.  The helpers here are shared with the literal front-to-back traversal
(:mod:`.octree_ftb`) and the literal sorted octree (:mod:`.octree_sort`).
"""

from __future__ import annotations

import numpy as np

from ...object import octree
from . import geometry


def literal_tree(segments, view, clip=None, tree=None):
    """The region octree to traverse: ``tree`` or one built from the segments; with a clip, the clipped object's."""
    if clip is not None:
        r = geometry.rotation(view.alpha, view.beta, view.gamma)
        return octree.build(geometry.clip_mask(segments.to_mask(), clip, r))
    return tree if tree is not None else octree.build(segments.to_mask())


def visible_faces(vpn):
    """``[(axis, side), ...]``: a face per axis whose VPN component is not zero, on the side it points to."""
    return [(axis, 1 if vpn[axis] > 0 else -1) for axis in range(3) if vpn[axis] != 0]


def children_front_to_back(vpn):
    """Child labels nearest first: the child on the viewer's side along every axis, then by how many axes
    it is away (ties by label).
    """
    near = [1 if v > 0 else 0 for v in vpn]
    away = {label: sum(int(octree.CHILD_OFFSETS[label][k]) != near[k] for k in range(3)) for label in range(8)}
    return sorted(range(8), key=lambda label: (away[label], label))


class FaceScan:
    """Scan-converts octant faces for one view, face by face, with the literal geometry."""

    def __init__(self, tree, view, shape):
        self.tree = tree
        self.r = geometry.rotation(view.alpha, view.beta, view.gamma)
        self.size, self.scale, self.middle = tuple(view.size), view.scale, tuple(view.centre)
        nz, ny, nx = shape
        self.centre = ((nx - 1) / 2, (ny - 1) / 2, (nz - 1) / 2)

    def vpn(self):
        return geometry.view_plane_normal(self.r)

    def face(self, node, axis, side):
        """``(pixels, scanlines)``: ``[(flat pixel, depth), ...]`` of the face and how many rows it covers."""
        side_length = int(self.tree.size(np.array([node]))[0])
        low = self.tree.origin[node].astype(float)
        box_centre = [low[k] + (side_length - 1) / 2 for k in range(3)]
        box_centre[axis] += side * side_length / 2
        half = [side_length / 2] * 3
        half[axis] = 0.0
        found = geometry.box_pixels(self.r, box_centre, half, self.centre, self.size, self.scale, self.middle)
        width = self.size[1]
        return [(row * width + column, depth) for row, column, depth in found], len({row for row, _, _ in found})


def render_octree_btf_literal(segments, view, clip=None, tree=None):
    """The oracle: recursive back-to-front traversal, black octants' faces painted one by one, each over
    what is behind.

    A ray along an edge that two faces share reaches both, which the paper's half-open scanline fill
    never does; there the nearer depth is kept, as in the contract.
    """
    tree = literal_tree(segments, view, clip, tree)
    scan = FaceScan(tree, view, segments.shape)
    vpn = scan.vpn()
    height, width = view.size
    image = np.full(height * width, np.inf)
    stats = {"white_visited": 0, "black_visited": 0, "grey_visited": 0, "black_faces": 0,
             "scanlines_accumulated": 0, "pixels_accumulated": 0, "pixel_writes": 0}
    back_to_front = children_front_to_back(vpn)[::-1]
    names = {octree.WHITE: "white", octree.BLACK: "black", octree.GREY: "grey"}

    def visit(node):
        color = int(tree.color[node])
        stats[f"{names[color]}_visited"] += 1
        if color == octree.BLACK:
            for axis, side in visible_faces(vpn):
                pixels, scanlines = scan.face(node, axis, side)
                for pixel, depth in pixels:             # painted in order: later (nearer) overwrites,
                    image[pixel] = min(image[pixel], depth)  # but a ray along a shared edge keeps the nearer
                stats["black_faces"] += 1
                stats["scanlines_accumulated"] += scanlines
                stats["pixels_accumulated"] += len(pixels)
                stats["pixel_writes"] += len(pixels)
        elif color == octree.GREY:
            for label in back_to_front:
                visit(int(tree.first_child[node]) + label)

    visit(0)
    return image.reshape(height, width).astype(np.float32), stats
