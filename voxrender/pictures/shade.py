"""From depth image to picture: Blinn-Phong lighting of surface normals, the paper's depth-gradient shading,
depth shading, 8/16-bit output.

The default lights the grey-level gradient normals (:mod:`voxrender.object.normals`, Höhne and Bernstein's shading)
with a headlight.  Depth-gradient shading (Gordon and Reynolds; the dynamic-screen paper's section 2.4)
estimates the normal at each pixel from the gradient of the depth image; it is kept as ``depth-gradient``.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError


def _depth_range(depth):
    covered = np.isfinite(depth)
    if not covered.any():
        return covered, 0.0, 1.0
    near, far = float(depth[covered].min()), float(depth[covered].max())
    return covered, near, max(far, near + 1e-6)


def _depth_cue(depth, strength):
    """``covered`` and a factor falling linearly from 1 at the nearest covered pixel to ``1 - strength`` at
    the farthest (of the type of ``depth``).
    """
    covered, near, far = _depth_range(depth)
    step = np.asarray(strength / (far - near), depth.dtype)
    return covered, np.where(covered, 1 - (depth - np.asarray(near, depth.dtype)) * step, 0).astype(depth.dtype)


def light_direction(light):
    """The unit vector toward ``light``, checked: three finite numbers, not all zero.

    >>> light_direction((0, 3, -4)).tolist()
    [0.0, 0.6, -0.8]
    """
    light = np.asarray(light, dtype=float)
    if light.shape != (3,) or not np.all(np.isfinite(light)) or not np.linalg.norm(light) > 0:
        raise InputError(f"{tuple(light.ravel().tolist())} must be a non-zero direction x, y, z", parameter="light")
    return light / np.linalg.norm(light)


def _depth_shading(depth, near_brightness=1.0, far_brightness=0.2):
    """Brightness in [0, 1] falling linearly from the nearest to the farthest covered pixel; 0 elsewhere.

    >>> _depth_shading(np.array([[0.0, 10.0, np.inf]])).round(2).tolist()
    [[1.0, 0.2, 0.0]]
    """
    covered, near, far = _depth_range(depth)
    out = np.zeros(depth.shape)
    out[covered] = near_brightness + (far_brightness - near_brightness) * (depth[covered] - near) / (far - near)
    return out


def _slope(depth, axis, scale):
    """dZ'/dX' (or dY') in voxel units: central difference, or the gentler one-sided one at edges and steps."""
    forward = np.full(depth.shape, np.nan)
    backward = np.full(depth.shape, np.nan)
    with np.errstate(invalid="ignore"):  # inf - inf between background pixels
        step = np.diff(depth, axis=axis) * scale
    step[~np.isfinite(step)] = np.nan
    lead = [slice(None)] * 2
    trail = [slice(None)] * 2
    lead[axis], trail[axis] = slice(None, -1), slice(1, None)
    forward[tuple(lead)] = step
    backward[tuple(trail)] = step
    both = np.isfinite(forward) & np.isfinite(backward)
    smooth = both & (np.abs(forward - backward) <= 2.0)
    gentler = np.where(np.abs(forward) <= np.abs(backward), forward, backward)
    one = np.where(np.isfinite(forward), forward, backward)
    slope = np.where(smooth, (forward + backward) / 2, np.where(both, gentler, one))
    return np.nan_to_num(slope, nan=0.0)


def _smooth_depth(depth, sigma):
    """Depth blurred over covered pixels only (normalised convolution); the background stays ``+inf``.

    Voxel depth images are terraced (every cube face is flat); a blur of about
    one voxel turns the terraces back into the surface they sample.

    >>> _smooth_depth(np.array([[0.0, 2.0, np.inf]]), 0.0).tolist()
    [[0.0, 2.0, inf]]
    """
    from skimage.filters import gaussian

    covered = np.isfinite(depth)
    if sigma <= 0 or not covered.any():
        return depth
    weight = gaussian(covered.astype(float), sigma=sigma, mode="constant")
    total = gaussian(np.where(covered, depth, 0.0), sigma=sigma, mode="constant")
    return np.where(covered, total / np.maximum(weight, 1e-12), np.inf)


def depth_normals(depth, scale=1.0, smoothing=0.0):
    """Unit normals ``(H, W, 3)`` in image space (pointing at the viewer, ``-Z'``) from the depth gradient.

    ``scale`` is pixels per voxel, so slopes come out in voxel units;
    ``smoothing`` is the blur in voxels applied to the depth first.

    >>> depth_normals(np.zeros((3, 3)))[1, 1].tolist()
    [0.0, 0.0, -1.0]
    """
    depth = _smooth_depth(depth, smoothing * scale)
    gx, gy = _slope(depth, 1, scale), _slope(depth, 0, scale)
    normals = np.stack([gx, gy, -np.ones_like(gx)], axis=-1)
    return normals / np.linalg.norm(normals, axis=-1, keepdims=True)


def gradient_shading(depth, scale=1.0, light=(0.0, 0.0, -1.0), ambient=0.1, depth_cue=0.25, smoothing=0.7):
    """Brightness in [0, 1]: Lambert shading of the depth-gradient normals, with a little depth cueing.

    Parameters
    ----------
    depth : ndarray (H, W)
        Depth image (``+inf`` background).
    scale : float
        Pixels per voxel of the view.
    light : 3 floats
        Direction toward the light in image space (X' right, Y' down, Z' away
        from the viewer); the default is a light at the viewer.
    ambient : float
        Brightness of surfaces facing away from the light.
    depth_cue : float
        How much darker the farthest surface is than the nearest (0 to 1).
    smoothing : float
        Blur of the depth, in voxels, before its gradient is taken (0: none).

    >>> flat = gradient_shading(np.zeros((3, 3)))
    >>> float(flat[1, 1])
    1.0
    """
    lambert = np.clip(depth_normals(depth, scale, smoothing) @ light_direction(light), 0, 1)
    covered, cue = _depth_cue(depth, depth_cue)
    return np.where(covered, (ambient + (1 - ambient) * lambert) * cue, 0.0)


# A headlight a little above and to the left of the viewer (image space: X' right, Y' down, Z' away).
HEADLIGHT = (-0.3, -0.4, -1.0)
SHADINGS = ("gradient", "depth-gradient", "depth")


def _blinn_phong(normals, depth, light=HEADLIGHT, ambient=0.12, diffuse=0.78, specular=0.22, shininess=24.0,
                depth_cue=0.2):
    """Brightness in [0, 1] of unit normals ``(..., 3)`` (image space) at depths ``(...)`` lit by a directional
    light, seen from ``-Z'``: ambient, Lambert diffuse and a Blinn-Phong highlight, darkened a little with depth
    (from the nearest to the farthest finite depth given); 0 where the depth is infinite.  Float32 throughout.

    >>> flat = np.zeros((1, 1, 3)); flat[..., 2] = -1
    >>> round(float(_blinn_phong(flat, np.zeros((1, 1)), light=(0, 0, -1))[0, 0]), 3)
    1.0
    """
    light = light_direction(light).astype(np.float32)
    halfway = light + np.array([0, 0, -1], np.float32)
    halfway = halfway / max(float(np.linalg.norm(halfway)), 1e-6)
    n = np.nan_to_num(np.asarray(normals, dtype=np.float32))
    total = np.clip(n @ light, 0, 1)
    total *= np.float32(diffuse)
    highlight = np.clip(n @ halfway, 0, 1)
    np.power(highlight, np.float32(shininess), out=highlight)
    total += np.float32(specular) * highlight + np.float32(ambient)
    np.clip(total, 0, 1, out=total)
    covered, cue = _depth_cue(np.asarray(depth, np.float32), depth_cue)
    total *= cue
    total[~covered] = 0
    return total


def ambient_occlusion(depth, scale=1.0, radius=3.0, directions=8, steps=3):
    """Screen-space ambient occlusion in [0, 1] (0: open, 1: buried) from the depth image alone.

    Each pixel looks ``steps`` times along ``directions`` directions up to ``radius`` voxels and counts how far
    nearer surfaces rise above it there (a horizon test), so creases and pits darken; the background occludes
    nothing.  The depth is first smoothed by about a voxel, so that the terraces of voxels do not read as
    creases.  The cost is ``directions x steps`` shifted comparisons of the picture.

    >>> pit = np.zeros((21, 21), np.float32); pit[8:13, 8:13] = 4.0     # a square pit, 4 voxels deep
    >>> occlusion = ambient_occlusion(pit)
    >>> bool(occlusion[10, 10] > 0.3), float(occlusion[0, 0])
    (True, 0.0)
    """
    depth = np.asarray(depth, dtype=np.float32)
    covered = np.isfinite(depth)
    # the terraces of a voxel depth image are not creases: look at the surface they sample
    filled = np.where(covered, _smooth_depth(depth, scale), np.inf).astype(np.float32)
    total = np.zeros(depth.shape, np.float32)
    reach = max(radius * scale, 1.0)
    for angle in np.arange(directions) * (2 * np.pi / directions):
        horizon = np.zeros(depth.shape, np.float32)
        for step in range(1, steps + 1):
            distance = reach * step / steps
            dy, dx = int(round(distance * np.sin(angle))), int(round(distance * np.cos(angle)))
            if dx == 0 and dy == 0:
                continue
            shifted = np.full(depth.shape, np.inf, np.float32)
            rows = slice(max(dy, 0), depth.shape[0] + min(dy, 0))
            columns = slice(max(dx, 0), depth.shape[1] + min(dx, 0))
            source_rows = slice(max(-dy, 0), depth.shape[0] + min(-dy, 0))
            source_columns = slice(max(-dx, 0), depth.shape[1] + min(-dx, 0))
            shifted[rows, columns] = filled[source_rows, source_columns]
            with np.errstate(invalid="ignore"):
                rise = (filled - shifted) / np.float32(np.hypot(dx, dy) / scale)     # slope toward the viewer
            np.maximum(horizon, np.nan_to_num(rise, nan=0.0, posinf=0.0, neginf=0.0), out=horizon)
        total += horizon / np.sqrt(1 + horizon * horizon)                     # sin of the horizon angle
    return np.where(covered, total / directions, 0.0).astype(np.float32)


def shade(depth, mode="gradient", scale=1.0, light=HEADLIGHT, colour=(1.0, 1.0, 1.0), background=(0, 0, 0),
          normals=None, occlusion=None):
    """An 8-bit RGB picture ``(H, W, 3)`` of a depth image.

    Parameters
    ----------
    depth : ndarray (H, W)
    mode : {"gradient", "depth-gradient", "depth"}
        ``gradient``: Blinn-Phong lighting of ``normals`` (grey-level gradient normals, see
        :mod:`voxrender.object.normals`), with the depth gradient's where they are missing; ``depth-gradient``: the
        paper's Lambert shading of the depth gradient; ``depth``: brightness falling with depth.
    scale : float
        Pixels per voxel (the depth gradient is measured in voxel units).
    light : 3 floats
        Direction toward the light in image space.
    colour : 3 floats in [0, 1]
        Colour of a fully lit surface.
    background : 3 ints in [0, 255]
    normals : ndarray (H, W, 3), optional
        Unit normals in image space, NaN where unknown (``gradient`` mode).
    occlusion : ndarray (H, W), optional
        Ambient occlusion in [0, 1] (:func:`ambient_occlusion`): darkens creases and pits.

    >>> rgb = shade(np.array([[0.0, np.inf]]), "depth", background=(0, 0, 255))
    >>> rgb.tolist()
    [[[255, 255, 255], [0, 0, 255]]]
    """
    covered = np.flatnonzero(np.isfinite(depth))          # the work is on the covered pixels only
    if mode == "gradient":
        lit = None if normals is None else np.asarray(normals, np.float32).reshape(-1, 3)[covered]
        missing = np.ones(len(covered), bool) if lit is None else ~np.isfinite(lit).all(axis=1)
        if missing.any():                                   # the depth gradient where no normal is known
            from_depth = depth_normals(depth, scale, 0.7).reshape(-1, 3)[covered].astype(np.float32)
            lit = from_depth if lit is None else np.where(missing[:, None], from_depth, lit)
        brightness = _blinn_phong(lit, np.asarray(depth, np.float32).ravel()[covered], light)
    elif mode == "depth-gradient":
        brightness = gradient_shading(depth, scale, light).ravel()[covered]
    elif mode == "depth":
        brightness = _depth_shading(depth).ravel()[covered]
    else:
        raise InputError(f"unknown shading {mode!r}; choose {', '.join(SHADINGS)}", parameter="shading")
    brightness = np.asarray(brightness, np.float32)
    if occlusion is not None:
        brightness *= 1 - np.float32(0.6) * np.asarray(occlusion, np.float32).ravel()[covered]
    colour = np.asarray(colour, np.float32)
    colour = colour.reshape(-1, 3)[covered] if colour.ndim == 3 else colour      # a colour per pixel, or one
    rgb = np.empty((depth.size, 3), np.uint8)
    rgb[:] = np.asarray(background, np.uint8)
    value = brightness[:, None] * (colour * np.float32(255))
    rgb[covered] = np.clip(np.rint(value), 0, 255)
    return rgb.reshape(*depth.shape, 3)


def normals_to_rgb(normals):
    """An 8-bit RGB normal map: each component from [-1, 1] to [0, 255]; black where unknown.

    >>> normals_to_rgb(np.array([[[0.0, 0.0, -1.0], [np.nan] * 3]])).tolist()
    [[[128, 128, 0], [0, 0, 0]]]
    """
    known = np.isfinite(normals).all(axis=2, keepdims=True)
    return np.where(known, np.clip(np.rint((np.nan_to_num(normals) + 1) * 127.5), 0, 255), 0).astype(np.uint8)


def depth_to_uint16(depth):
    """A 16-bit picture of depth: 65535 at the nearest covered pixel, 1 at the farthest, 0 for background.

    >>> depth_to_uint16(np.array([[0.0, 2.0, np.inf]])).tolist()
    [[65535, 1, 0]]
    """
    covered, near, far = _depth_range(depth)
    out = np.zeros(depth.shape, np.uint16)
    out[covered] = np.rint(1 + (far - depth[covered]) / (far - near) * 65534).astype(np.uint16)
    return out
