"""Cohort flags: what in a batch of segmentations looks unlike the rest, per label, to set the order of review.

A flag never replaces a look: it says why a study should be looked at first.  Each carries its value, the cohort's
(the median over the studies that have the label) and the limit it crossed:

- ``empty``: the label is there with 0 voxels;
- ``missing``: the study lacks a label other studies have (matched by
  :func:`voxrender._shared.label_sets.label_key`);
- ``volume``: a robust outlier, its modified z-score ``0.6745 (v - median) / MAD`` beyond ``Z_LIMIT``, the MAD
  floored at ``VOLUME_FLOOR`` of the median (and one voxel), so that near-identical volumes do not flag a voxel's
  difference;
- ``components``: more pieces than the cohort's usual (median) count;
- ``border``: it touches the edge of the field of view (it may be cut off);
- with a reference, ``dice`` and ``nsd`` below their limits.

References
----------
B. Iglewicz and D. C. Hoaglin, "How to Detect and Handle Outliers", ASQC Quality Press, 1993 (the modified z-score
and its limit of 3.5).
"""

from __future__ import annotations

import math
import statistics

from .._shared.label_sets import label_key

Z_LIMIT = 3.5
VOLUME_FLOOR = 0.05          # the MAD is at least this share of the median volume
COLUMNS = ("study", "label", "name", "flag", "value", "cohort", "limit")


def cohort_flags(rows, *, min_dice=0.8, min_nsd=None):
    """The flags of a batch's label rows.

    Parameters
    ----------
    rows : iterable of dict
        One a study and label: ``study``, ``label``, ``name``, ``voxels``, ``ml``; optionally ``components``,
        ``border`` (bool), and with a reference ``dice`` and ``nsd`` (a label the reference alone holds: ``voxels``
        None, with its Dice).
    min_dice, min_nsd : float, optional
        The limits below which agreement with the reference is flagged (``None``: not flagged).

    Returns
    -------
    list of dict
        ``COLUMNS`` each, in the order of the studies, then of the flags.

    Examples
    --------
    >>> rows = [{"study": s, "label": 1, "name": "liver", "voxels": v, "ml": v / 1000} for s, v in
    ...         [("a", 1500000), ("b", 1520000), ("c", 1490000), ("d", 400000), ("e", 1510000)]]
    >>> [(f["study"], f["flag"]) for f in cohort_flags(rows)]
    [('d', 'volume')]
    """
    rows = [dict(row) for row in rows]
    for row in rows:
        row["key"] = label_key(row.get("name"), row.get("label"))
    studies = list(dict.fromkeys(row["study"] for row in rows))
    by_key = {}
    for row in rows:
        by_key.setdefault(row["key"], []).append(row)
    flags = []
    for group in by_key.values():
        present = [r for r in group if (r.get("voxels") or 0) > 0]
        name = group[0].get("name") or f"label {group[0].get('label')}"
        flags += [_flag(r, "empty", 0, _median([p["ml"] for p in present]), "> 0") for r in group
                  if r.get("voxels") == 0]
        held = {r["study"] for r in present}
        if held:
            missing = [s for s in studies if s not in {r["study"] for r in group}]
            flags += [{"study": s, "label": group[0].get("label"), "name": name, "flag": "missing", "value": "",
                       "cohort": f"{len(held)} of {len(studies)} studies", "limit": "present"} for s in missing]
        flags += _volume_flags(present)
        pieces = [r["components"] for r in present if r.get("components") is not None]
        if pieces:
            usual = _median(pieces)
            flags += [_flag(r, "components", r["components"], usual, f"<= {usual:g}") for r in present
                      if r.get("components") is not None and r["components"] > usual]
        flags += [_flag(r, "border", "touches", "", "inside the field of view") for r in present if r.get("border")]
        for metric, limit in (("dice", min_dice), ("nsd", min_nsd)):
            scores = [r[metric] for r in group if _number(r.get(metric))]
            if limit is not None and scores:
                flags += [_flag(r, metric, r[metric], _median(scores), f">= {limit:g}") for r in group
                          if _number(r.get(metric)) and r[metric] < limit]
    order = {s: k for k, s in enumerate(studies)}
    return sorted(flags, key=lambda f: order.get(f["study"], len(order)))


def _volume_flags(present):
    """The robust outliers of the volumes of a label across the studies that have it."""
    if len(present) < 3:                               # no cohort to be unlike
        return []
    volumes = [r["ml"] for r in present]
    median = _median(volumes)
    voxel = min(r["ml"] / r["voxels"] for r in present)
    mad = max(_median([abs(v - median) for v in volumes]), VOLUME_FLOOR * abs(median), voxel)
    flags = []
    for row in present:
        z = 0.6745 * (row["ml"] - median) / mad
        if abs(z) > Z_LIMIT:
            flags.append({**_flag(row, "volume", row["ml"], median, f"|z| <= {Z_LIMIT:g}"), "z": round(z, 2)})
    return flags


def _flag(row, flag, value, cohort, limit):
    return {"study": row["study"], "label": row.get("label"), "name": row.get("name"), "flag": flag, "value": value,
            "cohort": cohort, "limit": limit}


def _median(values):
    return statistics.median(values) if values else ""


def _number(value):
    return isinstance(value, (int, float)) and not math.isnan(value)


def in_words(flag):
    """A flag's reason in words, as the index page shows it.

    >>> in_words({"flag": "volume", "value": 400.0, "cohort": 1500.0, "z": -10.2, "name": "liver"})
    'liver: volume 400 mL, the cohort 1500 (z -10.2)'
    >>> in_words({"flag": "volume", "value": 15.042, "cohort": 4.6069, "z": 6.5213, "name": "liver"})
    'liver: volume 15 mL, the cohort 4.61 (z 6.52)'
    """
    what = flag["flag"]
    name = flag.get("name") or f"label {flag.get('label')}"
    if what == "volume":
        value, cohort, z = (_three_digits(flag[key]) for key in ("value", "cohort", "z"))
        return f"{name}: volume {value} mL, the cohort {cohort} (z {z})"
    if what == "empty":
        return f"{name}: empty"
    if what == "missing":
        return f"{name}: missing (in {flag['cohort']})"
    if what == "components":
        return f"{name}: {flag['value']} pieces, the cohort {_three_digits(flag['cohort'])}"
    if what == "border":
        return f"{name}: touches the edge of the field of view"
    return f"{name}: {what} {flag['value']:.3f}, below {flag['limit'].removeprefix('>= ')}"


def _three_digits(value):
    """A number as a reader takes it in: three significant digits, never in exponent form."""
    return f"{float(f'{value:.3g}'):g}" if abs(value) < 1e6 else f"{value:.0f}"


def severity(flags):
    """How a study's flags order it: the lowest Dice with a reference, else the count of flags and the largest
    |z|; smaller is worse (a key to sort by).

    >>> severity([{"flag": "dice", "value": 0.42}]) < severity([{"flag": "volume", "value": 1.0, "z": 9.0}])
    True
    """
    dice = [f["value"] for f in flags if f["flag"] == "dice"]
    z = max((abs(f.get("z", 0)) for f in flags), default=0)
    return (min(dice) if dice else 1.0, -len(flags), -z)
