"""The projection section of the benchmark alone: voxrender's MIP beside VTK's on vhf_head.

    python -m benchmarks.projection [--repeat 5] [--data ../shared/data] [--pictures DIR]

``--pictures`` also writes both pictures of each view (PNG, the volume's full range as grey) to look at.
"""

from __future__ import annotations

import platform
from pathlib import Path

import click
import numpy as np

from benchmarks.bench import PROJECTION_VIEWS, VtkMipPeer, _projection_table, bench_projection


@click.command()
@click.option("--data", default=str(Path(__file__).resolve().parents[1].parent / "shared" / "data"),
              show_default=True, help="Folder holding vhf_head/.")
@click.option("--repeat", default=5, show_default=True, type=click.IntRange(1, 100))
@click.option("--pictures", default=None, type=click.Path(), help="Write both pictures of each view here.")
def main(data, repeat, pictures):
    """Time voxrender's MIP beside VTK's on vhf_head, 512 x 512 at scale 1."""
    from voxrender import io

    path = Path(data) / "vhf_head"
    if not path.is_dir():
        raise SystemExit(f"error: {path} is absent; the benchmark needs ../shared/data (or --data)")
    values = io.read_volume(path).values
    try:
        peer = VtkMipPeer(values)
    except ImportError:
        peer = None
    result = bench_projection(values, repeat, peer=peer)
    click.echo(f"{platform.machine()}, {platform.python_version()}, numpy {np.__version__}\n")
    click.echo("\n".join(_projection_table(result)))
    if pictures:
        _write_pictures(values, peer, Path(pictures))


def _write_pictures(values, peer, folder):
    from voxrender.outputs import output
    from voxrender.pictures._project import project
    from voxrender.pictures.display import DisplayWindow
    from voxrender.space.view import View

    folder.mkdir(parents=True, exist_ok=True)
    low, high = float(values.min()), float(values.max())
    window = DisplayWindow((low + high) / 2, high - low)
    for k, angles in enumerate(PROJECTION_VIEWS.values()):
        view = View(*angles, (512, 512), 1.0)
        grey = window.to_uint8(project(values, view, "mip"))
        output.write_png(folder / f"voxrender_{k}.png", np.repeat(grey[..., None], 3, axis=2))
        if peer is not None:
            output.write_png(folder / f"vtk_{k}.png", np.ascontiguousarray(peer.picture(view)))


if __name__ == "__main__":
    main()
