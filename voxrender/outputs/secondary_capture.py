"""Pictures a PACS can show: an RGB DICOM Secondary Capture in a new series of the study its CT came from.

PACS viewers seldom show a DICOM SEG, but every one of them shows a Secondary Capture.  :func:`dicom_study` reads
what a new picture needs of its source series (headers only); :func:`write_secondary_capture` writes the picture as
a Secondary Capture Image (highdicom's ``SCImage``) that joins the source's patient and study, in a series of its
own, and references every source image.  :func:`write_dicom_output` is the writer of the ``dicom`` record of
:data:`voxrender.outputs.output_kinds.OUTPUTS`.

pydicom and highdicom are imported inside the functions: the command line imports this module at start-up.

References
----------
.. [1] DICOM PS3.3, A.8.1 Secondary Capture Image IOD; C.7.6.1 General Image module (Image Type, Patient
       Orientation); C.12.4 General Reference module (Derivation Description, Source Image Sequence); C.12.2 Common
       Instance Reference module (Referenced Series Sequence); C.8.6.1 SC Equipment module (Conversion Type).
       https://dicom.nema.org/medical/dicom/current/output/html/part03.html
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._shared.files import atomic_output
from ..errors import InputError

SERIES_NUMBER_OFFSET = 1000         # the pictures' series sorts after its source's in a PACS's series list
DESCRIPTION_LIMIT = 1024            # DerivationDescription is an ST: at most 1024 characters
_PATIENT_LETTERS = str.maketrans("SI", "HF")   # DICOM names the head and the feet H and F, not S and I


@dataclass(frozen=True)
class DicomStudy:
    """What a new picture needs of the DICOM series it was made from.

    Parameters
    ----------
    reference : pydicom.Dataset
        One source image's header (no pixels): its patient, study and equipment modules go into the picture.
    images : tuple of (str, str)
        ``(SOPClassUID, SOPInstanceUID)`` of every image of the series, each referenced by the picture.
    series_uid : str
        The source's SeriesInstanceUID.
    source : str
        The path it was read from, for messages.
    """

    reference: object
    images: tuple
    series_uid: str
    source: str


def _not_dicom(path):
    return InputError(f"{path} is not DICOM, so the picture has no study to join; name the DICOM series it was "
                      "made from", parameter="dicom_study_from")


def dicom_study(path, series=None):
    """Read the headers of the DICOM series a picture was made from.

    Parameters
    ----------
    path : str or Path
        A folder of DICOM files (its files may be nested, as exports do), or one DICOM file: an enhanced
        multi-frame image, or one slice of a folder (its series in that folder is taken).
    series : str, optional
        The SeriesInstanceUID of the series, when the folder holds several.

    Returns
    -------
    DicomStudy

    Raises
    ------
    InputError
        ``path`` is not DICOM (``parameter="dicom_study_from"``), holds several series and ``series`` chooses none
        (``parameter="series"``), or a file is damaged.

    Examples
    --------
    >>> try:
    ...     dicom_study("/no/such/series")
    ... except InputError as error:
    ...     print(error.parameter, "|", error.message.split(";")[0])
    dicom_study_from | /no/such/series is not DICOM, so the picture has no study to join
    """
    from ..io.dicomfile import dicom_files, is_dicom

    path = Path(path)
    if path.is_file():
        if not is_dicom(path):
            raise _not_dicom(path)
        header = _header(path, _HEADER_TAGS)
        if _frames(header) > 1:                           # a multi-frame image is a series of its own
            files = [path]
        else:                                             # one slice: its series, in its folder
            files, series = dicom_files(path.parent), str(header.get("SeriesInstanceUID", ""))
    elif path.is_dir():
        files = dicom_files(path)
    else:
        files = []
    if not files:
        raise _not_dicom(path)
    chosen = _choose_series(_image_headers(files, path), path, series)
    reference = _header(chosen[0][0])
    if "StudyInstanceUID" not in reference:
        raise InputError(f"{chosen[0][0]} has no StudyInstanceUID, so the picture has no study to join; name a DICOM "
                         "series from a study", parameter="dicom_study_from")
    images = tuple((str(ds.SOPClassUID), str(ds.SOPInstanceUID)) for _, ds in chosen)
    return DicomStudy(reference, images, str(reference.get("SeriesInstanceUID", "")), str(path))


# The elements that tell the images of a folder and their series apart (read of every file).
_HEADER_TAGS = ("SOPClassUID", "SOPInstanceUID", "SeriesInstanceUID", "SeriesDescription", "Modality",
                "NumberOfFrames", "InstanceNumber", "Rows")


def _header(path, tags=None):
    """The header of DICOM file ``path`` (no pixels; only ``tags`` when given), or an :class:`InputError`."""
    import pydicom

    from .._shared.text import first_line
    from ..io.dicomfile import BoundedFile, damaged_file_errors

    try:
        with BoundedFile(path) as stream:      # a damaged length would otherwise allocate what it says first
            ds = pydicom.dcmread(stream, stop_before_pixels=True, force=True, specific_tags=tags)
        for keyword in tags or ():              # pydicom decodes a value when first asked: a damaged one fails here
            ds.get(keyword)
    except damaged_file_errors() as exc:
        raise InputError(f"cannot read DICOM file {path}: {first_line(exc)}") from None     # the file is at fault
    return ds


def _frames(ds):
    try:
        return int(ds.get("NumberOfFrames", 1) or 1)
    except (TypeError, ValueError):
        return 1


def _image_headers(files, path):
    """``[(file, header)]`` of the images among ``files``: segmentations, reports and plans beside them are not."""
    from ..io.dicomfile import NOT_IMAGES, SEGMENTATIONS

    headers = []
    for f in files:
        ds = _header(f, _HEADER_TAGS)
        if str(ds.get("SOPClassUID", "")) in SEGMENTATIONS or str(ds.get("Modality", "")) in NOT_IMAGES:
            continue
        if "SOPClassUID" not in ds or "SOPInstanceUID" not in ds:
            raise InputError(f"DICOM file {f} has no SOPClassUID or SOPInstanceUID, so the picture cannot reference "
                             "it; the file is damaged")
        headers.append((f, ds))
    if not headers:
        raise InputError(f"{path} holds no DICOM images, only segmentations or reports; name the DICOM series the "
                         "picture was made from", parameter="dicom_study_from")
    return headers


def _choose_series(headers, path, series):
    """The headers of one series, as :func:`voxrender.io.dicom.read_dicom` chooses it, in instance-number order."""
    from ..io.dicomfile import choose_series

    groups = {}
    for f, ds in headers:
        groups.setdefault(str(ds.get("SeriesInstanceUID", "(no SeriesInstanceUID)")), []).append((f, ds))
    chosen = choose_series(groups, path, series)

    def number(item):
        try:
            return int(item[1].get("InstanceNumber"))
        except (TypeError, ValueError):
            return 0

    return sorted(chosen, key=number)


def write_secondary_capture(path, rgb, study, description, series_description="voxrender pictures",
                            series_uid=None, instance_number=1, *, orientation=None):
    r"""Write ``rgb`` as an RGB DICOM Secondary Capture Image in a new series of ``study``'s study, atomically.

    The picture keeps the source's patient and study modules (highdicom's ``SCImage.from_ref_dataset``; the
    source's equipment becomes its contributing equipment) and has a new SeriesInstanceUID (or ``series_uid``, so
    that several pictures of one study share a series) and SOPInstanceUID.  It is ImageType
    ``DERIVED\SECONDARY\OTHER``, ConversionType ``WSD`` (made on a workstation), Manufacturer ``voxrender`` with its
    version as SoftwareVersions, DerivationDescription ``description``, and it references every source image: in
    the SourceImageSequence (General Reference module) and, as the Common Instance Reference module asks of an
    instance that references others of its study, in the ReferencedSeriesSequence.

    Parameters
    ----------
    path : str or Path
        The ``.dcm`` file to write.
    rgb : ndarray of uint8, (H, W, 3)
        The picture.
    study : DicomStudy
        The source series, from :func:`dicom_study`.
    description : str
        How the picture was made (see :func:`describe`); cut to 1024 characters.
    series_description : str
        The new series' SeriesDescription.
    series_uid : str, optional
        The SeriesInstanceUID of the new series (default: a new UID).
    instance_number : int
        The picture's InstanceNumber in its series.
    orientation : (str, str), optional
        PatientOrientation: the patient directions along the picture's rows and down its columns (``("L", "F")``
        for a picture from the front); empty when not given, as the standard allows for a Secondary Capture.

    References
    ----------
    .. [1] DICOM PS3.3, A.8.1 Secondary Capture Image IOD; C.12.4 General Reference module; C.12.2 Common
           Instance Reference module.

    Examples
    --------
    >>> import tempfile
    >>> from pydicom import Dataset
    >>> source = Dataset()
    >>> source.StudyInstanceUID, source.PatientID = "1.2.3", "P1"
    >>> study = DicomStudy(source, (("1.2.840.10008.5.1.4.1.1.2", "1.2.3.4"),), "1.2.3.9", "ct/")
    >>> path = Path(tempfile.mkdtemp()) / "picture.dcm"
    >>> write_secondary_capture(path, np.zeros((4, 6, 3), np.uint8), study, "a test")
    >>> import pydicom
    >>> sc = pydicom.dcmread(path)
    >>> sc.PatientID, sc.StudyInstanceUID, sc.pixel_array.shape, sc.DerivationDescription
    ('P1', '1.2.3', (4, 6, 3), 'a test')
    """
    import highdicom as hd
    from pydicom import Dataset
    from pydicom.uid import ExplicitVRLittleEndian, generate_uid

    from .. import __version__

    rgb = np.asarray(rgb)
    if rgb.dtype != np.uint8 or rgb.ndim != 3 or rgb.shape[2] != 3:
        raise InputError(f"a Secondary Capture holds an RGB picture, (H, W, 3) uint8, not {rgb.dtype} {rgb.shape}",
                         parameter="rgb")
    source = study.reference
    # highdicom asks a picture of a patient for its orientation; one it is not told is left empty below
    letters = [str(v).translate(_PATIENT_LETTERS) for v in orientation] if orientation else ["L", "F"]
    with warnings.catch_warnings():
        # the names are the source's, copied as they are: how its scanner wrote them ("Eve") is not for this
        # picture to warn of
        warnings.filterwarnings("ignore", "The string .* is unlikely to represent the intended person name")
        sc = hd.sc.SCImage.from_ref_dataset(
            source, pixel_array=np.ascontiguousarray(rgb), photometric_interpretation="RGB", bits_allocated=8,
            coordinate_system="PATIENT", series_instance_uid=series_uid or generate_uid(),
            series_number=_series_number(source), sop_instance_uid=generate_uid(),
            instance_number=int(instance_number), manufacturer="voxrender",
            patient_orientation=tuple(v[0] for v in letters), transfer_syntax_uid=ExplicitVRLittleEndian,
            series_description=series_description, software_versions=__version__)
    sc.PatientOrientation = letters if orientation else None     # "LP", "HA": an oblique side keeps both letters
    sc.ConversionType = "WSD"
    sc.DerivationDescription = description[:DESCRIPTION_LIMIT]

    def reference(sop_class, sop_instance):
        item = Dataset()
        item.ReferencedSOPClassUID, item.ReferencedSOPInstanceUID = sop_class, sop_instance
        return item

    sc.SourceImageSequence = [reference(*image) for image in study.images]
    series = Dataset()
    series.SeriesInstanceUID = study.series_uid
    series.ReferencedInstanceSequence = [reference(*image) for image in study.images]
    sc.ReferencedSeriesSequence = [series]
    with atomic_output(path) as tmp:
        sc.save_as(tmp, enforce_file_format=True)


def _series_number(source):
    """The new series' number: the source's plus :data:`SERIES_NUMBER_OFFSET`, so the same for every picture of it."""
    try:
        return SERIES_NUMBER_OFFSET + int(source.get("SeriesNumber", 0) or 0)
    except (TypeError, ValueError):
        return SERIES_NUMBER_OFFSET


def describe(result, about=None):
    """How a picture was made, in one line: voxrender's version, the method, the view, the object's threshold or
    labels and the projection (the DerivationDescription of its Secondary Capture).

    Parameters
    ----------
    result : Picture
        The finished picture (its ``image`` gives the method and view; a ``projection`` attribute, when it has one,
        the projection).
    about : dict, optional
        The picture's report fields (see :func:`voxrender.outputs.picture_outputs.about`): ``about["object"]`` holds the
        object's ``threshold``, ``labels``, ``label_table`` and ``label_source``; ``about["projection"]`` a projection.

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> from voxrender.space.view import View
    >>> result = SimpleNamespace(image=SimpleNamespace(method="ftb", view=View(90, 0, 0)))
    >>> describe(result, {"object": {"threshold": 300}})
    'voxrender 0.2.0: ftb, view alpha 90 beta 0 gamma 0, threshold 300'
    >>> describe(result, {"object": {"labels": [1, 2], "label_source": "seg.nii.gz",
    ...                              "label_table": {"1": {"name": "liver"}}}})
    'voxrender 0.2.0: ftb, view alpha 90 beta 0 gamma 0, labels 1 liver, 2 of seg.nii.gz'
    """
    from .. import __version__

    about = about or {}
    meta = about.get("object") or {}
    image = getattr(result, "image", None)
    projection = about.get("projection") or getattr(result, "projection", None)
    parts = []
    if getattr(image, "method", None) and image.method != projection:    # a projection's method is its mode
        parts.append(str(image.method))
    view = getattr(image, "view", None)
    if view is not None:
        parts.append(f"view alpha {view.alpha:g} beta {view.beta:g} gamma {view.gamma:g}")
    if projection:
        parts.append(f"projection {projection}")
    if getattr(result, "shows", None):                    # a composite picture says what it shows itself
        parts.append(result.shows)
    return f"voxrender {__version__}: " + ", ".join(parts + selection_words(meta))


def selection_words(meta):
    """The threshold and labels an object was selected by, from its ``meta``, as parts of a description (a label
    map by its file's name alone: a local path means nothing in a PACS).

    >>> selection_words({"threshold": 300, "labels": [2], "label_source": "/data/seg.nii.gz"})
    ['threshold 300', 'labels 2 of seg.nii.gz']
    """
    parts = []
    threshold = meta.get("threshold")
    if threshold is not None:                   # a number, or a window in words ("-100:300")
        parts.append(f"threshold {threshold:g}" if isinstance(threshold, (int, float)) else f"threshold {threshold}")
    if meta.get("labels"):
        table = meta.get("label_table") or {}
        names = [f"{label} {table[str(label)]['name']}" if str(label) in table and table[str(label)].get("name")
                 else str(label) for label in meta["labels"]]
        source = f" of {Path(meta['label_source']).name}" if meta.get("label_source") else ""
        parts.append(f"labels {', '.join(names)}{source}")
    return parts


def write_dicom_output(path, result, about):
    """The ``dicom`` output of :data:`voxrender.outputs.output_kinds.OUTPUTS`: ``result.rgb`` as a Secondary Capture.

    ``about["dicom_study"]`` is the :class:`DicomStudy` of the source (set by the command that read it);
    ``about["dicom_series_uid"]`` and ``about["dicom_instance_number"]``, when given, place the picture in a series
    shared with the other pictures of the study.  The PatientOrientation is the view's, when the object's
    orientation is known (``about["object"]["orientation_from"]``).
    """
    about = about or {}
    study = about.get("dicom_study")
    if study is None:
        raise InputError("a DICOM picture joins the study of the DICOM series it was made from, and none was given; "
                         "name that series", parameter="dicom_study_from")
    from ..space.orient import in_patient_frame

    view = getattr(getattr(result, "image", None), "view", None)
    orientation = None
    made_of = about.get("object") or {}
    if view is not None and made_of.get("orientation") and in_patient_frame(made_of):   # its edges' directions
        from ..pictures.marks import edge_letters

        edges = edge_letters(view)
        orientation = (edges["right"], edges["bottom"])      # along a row (left to right), down a column
    write_secondary_capture(path, result.rgb, study, describe(result, about),
                            series_uid=about.get("dicom_series_uid"),
                            instance_number=about.get("dicom_instance_number", 1), orientation=orientation)
