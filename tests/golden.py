"""The golden pictures: what each case renders to, and ``make golden`` to rewrite them after an intended change.

Look at every picture before committing new ones.  A case is the command line of ``voxrender`` that makes it;
``{samples}`` is a folder of the built-in samples and ``{data}`` the real data in ``../shared/data``.
"""

import sys
import tempfile
import warnings
from pathlib import Path

from click.testing import CliRunner

from voxrender._render import METHODS
from voxrender.cli import main

GOLDEN = Path(__file__).resolve().parent / "golden"
DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
SHELL = ["render", "{samples}/shell", "--threshold", "500", "--alpha", "100", "--beta", "20", "--size", "96"]
CASES = {
    "demo": ["demo", "--size", "96"],  # the quarter head shipped with voxrender
    **{f"shell-{method}": SHELL + ["--method", method] for method in sorted(METHODS)},
    "shell-gamma": SHELL + ["--gamma", "30"],
    "shell-cutaway": SHELL + ["--cut-depth", "0", "--light", "1,-1,-2"],
    "headsq-bone": ["render", "{data}/headsq", "--raw", "64x64:uint16:little", "--spacing", "3.2,3.2,1.5",
                    "--threshold", "1150", "--view", "anterior", "--size", "128"],
    # vhf_head with its label map by HU ranges (bone, soft tissue, airway), cut open
    "head-labels": ["render", "{data}/vhf_head", "--labels-from", "{samples}/head.seg.nrrd", "--voxel", "2",
                    "--alpha", "90", "--beta", "60", "--clip-x", ":128", "--legend", "--size", "160"],
    # the same labels as a DICOM SEG of the real series, written by highdicom, placed by position
    "head-seg": ["render", "{data}/vhf_head", "--labels-from", "{samples}/head-seg.dcm", "--voxel", "2",
                 "--alpha", "90", "--beta", "60", "--clip-x", ":128", "--legend", "--size", "160"],
    # the QC pictures: its slices with the labels filled and outlined, and an oblique MIP
    "head-slices": ["slices", "{data}/vhf_head", "--labels-from", "{samples}/head.seg.nrrd", "--overlay", "both",
                    "--legend", "--size", "128"],
    "head-mip": ["render", "{data}/vhf_head", "--threshold", "300", "--projection", "mip", "--alpha", "30", "--beta",
                 "10", "--size", "128"],
    # levels of detail: vhf_head's skin encoded with --levels, drawn from its 2x level, and at a size whose pixel
    # is eight voxels, which the level 8 times coarser suits
    "head-level1": ["render", "{samples}/head-levels.vxs", "--level", "1", "--alpha", "90", "--beta", "30",
                    "--size", "160"],
    "head-level-auto": ["render", "{samples}/head-levels.vxs", "--alpha", "90", "--beta", "30", "--size", "56"],
}
REAL_DATA = {"headsq-bone", "head-labels", "head-seg", "head-slices", "head-mip", "head-level1", "head-level-auto"}


def head_labels(samples, data):
    """The label map of vhf_head by HU ranges (``samples.tissue_labels``), with its names and colours as a
    ``.seg.nrrd``, made once into ``samples``."""
    from voxrender.io import read_volume
    from voxrender.outputs.output import write_nrrd
    from voxrender.samples import TISSUES, segment_fields, tissue_labels

    target = Path(samples) / "head.seg.nrrd"
    if not target.is_file():
        volume = read_volume(Path(data) / "vhf_head")
        write_nrrd(target, tissue_labels(volume.values), volume.spacing, segment_fields(TISSUES),
                   volume.meta["origin"])


def head_seg(samples, data):
    """The label map of :func:`head_labels` as a DICOM SEG (BINARY, named and coloured) of vhf_head's own slices,
    made once into ``samples`` with highdicom from copies of the slices (highdicom asks of its sources attributes
    they lack, which are added to the copies)."""
    import shutil

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from seg_files import complete_sources, write_seg

    from voxrender.io import read_volume
    from voxrender.samples import TISSUES, tissue_labels

    target = Path(samples) / "head-seg.dcm"
    if target.is_file():
        return
    copies = Path(samples) / "vhf_sources"
    shutil.copytree(Path(data) / "vhf_head", copies, dirs_exist_ok=True)
    with warnings.catch_warnings():            # pydicom's and highdicom's note on the one-word PatientName
        warnings.simplefilter("ignore")
        sources = sorted(complete_sources(sorted(copies.iterdir())),
                         key=lambda ds: float(ds.ImagePositionPatient[2]))
        labels = tissue_labels(read_volume(Path(data) / "vhf_head").values)       # [z, y, x], z from the feet up
        names, colours = zip(*(TISSUES[k] for k in sorted(TISSUES)), strict=True)
        write_seg(target, sources, labels, list(names), colours=list(colours))
    shutil.rmtree(copies)


def head_levels(samples, data):
    """vhf_head's skin (-300 HU) encoded with its levels of detail into ``samples``, once."""
    target = Path(samples) / "head-levels.vxs"
    if not target.is_file():
        result = CliRunner().invoke(main, ["encode", str(Path(data) / "vhf_head"), "--threshold", "-300", "--levels",
                                           "-o", str(target)])
        assert result.exit_code == 0, result.output


def render_case(name, output, samples, data=DATA):
    """Run the case's command, writing its picture to ``output``."""
    args = [a.format(samples=samples, data=data) for a in CASES[name]] + ["-o", str(output)]
    if name != "demo" and not (Path(samples) / "shell").is_dir():
        CliRunner().invoke(main, ["samples", str(samples)])
    if name in ("head-labels", "head-slices"):
        head_labels(samples, data)
    if name == "head-seg":
        head_seg(samples, data)
    if name.startswith("head-level"):
        head_levels(samples, data)
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, (args, result.output)


if __name__ == "__main__":
    names = sys.argv[1:] or list(CASES)
    with tempfile.TemporaryDirectory() as folder:
        for name in names:
            render_case(name, GOLDEN / f"{name}.png", Path(folder) / "samples")
            print(GOLDEN / f"{name}.png")
