"""``voxrender encode``: an input's object as run-length segments (``.vxs``), with its octrees (``.vxo``)."""

from __future__ import annotations

from pathlib import Path

import click

from .._shared.files import check_writable
from ..batch import parse
from ..errors import InputError
from ..object.pipeline import is_segments_file
from ._main import main, progress
from ._options import check_vxs_options, input_flags, max_memory_flag, prep_flags, prep_options_of, read_options_of


@main.command("encode")
@input_flags
@prep_flags
@click.option("-o", "--output", "output_path", required=True, type=click.Path(path_type=Path),
              help=".vxs file to write (.vxo with --octree).")
@click.option("--octree", "as_octree", is_flag=True,
              help="Also keep the region octree, linear octree and face adjacency (.vxo), so that octree methods "
                   "rendering from it pay only their traversal.")
@click.option("--jobs", type=click.IntRange(1, 1024),
              help="Worker processes encoding slabs of a streamed stack at once (default: the machine's cores, as "
                   "many as --max-memory holds).")
@click.option("--scheduler", metavar="ADDRESS|local",
              help="Encode the slabs on a Dask cluster ('local' starts one here); its workers read INPUT's path.")
@click.option("--levels", is_flag=True,
              help="Also keep the object at 2, 4 and 8 times coarser voxels (a voxel in them when any of its voxels "
                   "is), which render draws pictures coarser than the voxels from (render --level). Adds them to a "
                   ".vxs given as INPUT.")
@max_memory_flag
def encode_command(input_path, output_path, as_octree, levels, jobs, scheduler, max_memory, **options):
    """Select the object of INPUT and save its run-length segments (.vxs), with its octrees (.vxo).

    A stack larger than --max-memory is read a slab at a time (streamed), in bounded memory.
    """
    suffix = ".vxo" if as_octree else ".vxs"
    if output_path.suffix.lower() != suffix:
        raise InputError(f"the output {output_path} must end in {suffix}")
    if is_segments_file(input_path) and not (as_octree or levels):
        raise InputError(f"{input_path} is already encoded; --octree or --levels add to it")
    check_vxs_options(input_path, options)
    check_writable(output_path)
    from ..object import stream

    loaded, how = stream.encode_file(input_path, output_path, read_options_of(options), prep_options_of(options),
                              octree=as_octree, levels=levels, jobs=jobs, scheduler=scheduler,
                              max_memory=parse.memory(max_memory) if max_memory else None, progress=progress)
    s = loaded.segments
    nz, ny, nx = s.shape
    chosen = [f"threshold {s.meta['threshold']}"] if "threshold" in s.meta else []
    if "labels" in s.meta:
        chosen.append(f"{len(s.meta['labels'])} labels" + (" as one object" if s.labels is None else ""))
    if s.meta.get("binned"):
        chosen.append(f"binned by {s.meta['binned']}")
    if how:
        chosen.append(f"streamed ({how})")
    if s.levels:
        chosen.append("levels " + ", ".join(f"{level.meta['level_factor']}x" for level in s.levels))
    click.echo(f"{output_path}: {nx}x{ny}x{nz} voxels, {s.voxel_count} in the object, {s.segment_count} segments"
               + "".join(f", {c}" for c in chosen) + f", {loaded.seconds['encode']:.1f} s")
    if as_octree:
        tree = loaded.octree()
        counts = tree.counts()
        click.echo(f"  a {1 << tree.n}^3 octree: {counts['black']} black, {counts['white']} white, {counts['grey']} "
                   f"grey nodes; {len(tree.linear)} linear-octree codes")
