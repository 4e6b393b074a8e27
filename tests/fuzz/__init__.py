"""The fuzzing gate (``make fuzz``): small valid files of every format voxrender reads, each damaged one way, each
rendered by the CLI in a subprocess with a memory and a time limit.

Every case must end in a picture, or in exit 2 with one error line (warnings before it are fine); an internal error
(exit 1), a signal, a time-out, the memory limit, a traceback, a partial output, an output outside its folder or a
modified input is a misbehaviour, and the gate fails.  Case ``n`` of seed ``s`` is always the same file
(:func:`~fuzz.cases.make_case`), with a short name saying what was done to it (``"nifti/pixdim[1]=nan"``); every
misbehaving case is kept under ``tests/fuzz_cases/<outcome>/<name>/`` with its ``case.json``, which
``tests/test_fuzz_subset.py`` replays.

    python -m tests.fuzz [--seed S] [--cases N] [--jobs J] [--keep FOLDER]

Valid files are written by the libraries that write those formats (nibabel, pynrrd, pydicom, tifffile, imageio,
numpy, voxrender's own ``.vxs`` writer); header fields are changed through them where they can be (a nibabel
header field, a pydicom data element, a ``.npy`` header dict), and as ``key: value`` text where the header is text
(NRRD, MetaImage); bytes are cut, flipped and garbled on the written files.
"""

import sys
from pathlib import Path

TESTS = Path(__file__).resolve().parents[1]
if str(TESTS) not in sys.path:      # formats.py and dicom_files.py, the suite's writers of valid files
    sys.path.insert(0, str(TESTS))
