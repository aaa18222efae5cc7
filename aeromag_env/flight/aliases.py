"""Field-name aliases: every name a flight file may use for a channel, mapped to ours, in one table.

Our names are those of the SGL 2020 data set (:data:`SGL_2020_FIELDS`, plus ``alt``, ``maneuver``
and ``truth_*``). A reader hands its fields over under the names the file uses;
:func:`apply_aliases` renames the ones listed here, records what it did in
``attrs["aliases"]`` (``{canonical: original}``) and returns one warning line saying so. Nothing is
dropped: when a file holds both a canonical name and one of its aliases (or two aliases of one
name), the canonical field (else the first alias in file order) takes the name, the other keeps
its own and a warning says so.

Matching ignores case, so ``TT``, ``LAT`` or ``Diurnal`` are also read as ``tt``, ``lat``,
``diurnal``: any case variant of a canonical name is an alias of it. Rows with ``<n>`` stand for
a magnetometer number (1, 2, …) and ``<s>`` for a fluxgate letter (a, b, …).

Sources: the SGL field lists (MagNav.jl ``readmes/sgl_2020_fields_readme.txt``,
``sgl_2021_fields_readme.txt``), the column list of SGL's Geosoft XYZ export
(``readmes/Data-readme.txt``) and the names read by MagNav.jl's first flight-data reader
(``get_flight_data``) and by its ``get_XYZ0``. The SGL 2021 files use the 2020 names (a subset,
without radar, topo, dem, drape, ogs_*, mag_6_uc and the avionics rates), so they need no row.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from typing import Any, NamedTuple

import numpy as np


class Alias(NamedTuple):
    """One row of the alias table: a name found in files, ours, and where it comes from."""

    original: str
    canonical: str
    source: str


XYZ = "Geosoft XYZ (SGL export)"
MAGNAV_OLD = "MagNav.jl, first reader (get_flight_data)"
MAGNAV_XYZ0 = "MagNav.jl get_XYZ0 (trajectory attitude)"

#: Every alias, in the order the README lists them.
ALIASES: tuple[Alias, ...] = (
    # Geosoft XYZ: the column names of SGL's XYZ export
    Alias("TIME", "tt", XYZ),
    Alias("LINE", "line", XYZ),
    Alias("FLT", "flight", XYZ),
    Alias("LONG", "lon", XYZ),
    Alias("UTM-X", "utm_x", XYZ),
    Alias("UTM-Y", "utm_y", XYZ),
    Alias("UTM-Z", "utm_z", XYZ),
    Alias("MSL-Z", "msl", XYZ),
    Alias("ROLL", "ins_roll", XYZ),
    Alias("PITCH", "ins_pitch", XYZ),
    Alias("AZIMUTH", "ins_yaw", XYZ),
    Alias("UNCOMPMAG<n>", "mag_<n>_uc", XYZ),
    Alias("COMPMAG<n>", "mag_<n>_c", XYZ),
    Alias("LAGMAG<n>", "mag_<n>_lag", XYZ),
    Alias("DCMAG<n>", "mag_<n>_dc", XYZ),
    Alias("IGRFMAG<n>", "mag_<n>_igrf", XYZ),
    Alias("FLUX<s>_X", "flux_<s>_x", XYZ),
    Alias("FLUX<s>_Y", "flux_<s>_y", XYZ),
    Alias("FLUX<s>_Z", "flux_<s>_z", XYZ),
    Alias("FLUX<s>_TOT", "flux_<s>_t", XYZ),
    Alias("OGS_HGT", "ogs_alt", XYZ),
    Alias("INS_HGT", "ins_alt", XYZ),
    Alias("INS_VEL_N", "ins_vn", XYZ),
    Alias("INS_VEL_W", "ins_vw", XYZ),
    Alias("INS_VEL_V", "ins_vu", XYZ),
    Alias("PITCHRT", "pitch_rate", XYZ),
    Alias("ROLLRT", "roll_rate", XYZ),
    Alias("YAWRT", "yaw_rate", XYZ),
    Alias("LONG_ACC", "lgtl_acc", XYZ),
    Alias("LAT_ACC", "ltrl_acc", XYZ),
    Alias("NORM_ACC", "nrml_acc", XYZ),
    Alias("TRUE_AS", "tas", XYZ),
    Alias("TOT_P", "total_p", XYZ),
    Alias("CUR_COM1", "cur_com_1", XYZ),
    Alias("CUR_ACHi", "cur_ac_hi", XYZ),
    Alias("CUR_ACLo", "cur_ac_lo", XYZ),
    Alias("CUR_IHTR", "cur_heat", XYZ),
    Alias("CUR_BAT1", "cur_bat_1", XYZ),
    Alias("CUR_BAT2", "cur_bat_2", XYZ),
    Alias("V_ACPWR", "vol_acpwr", XYZ),
    Alias("V_OUTPWR", "vol_outpwr", XYZ),
    Alias("V_BAT1", "vol_bat_1", XYZ),
    Alias("V_BAT2", "vol_bat_2", XYZ),
    Alias("V_RESp", "vol_res_p", XYZ),
    Alias("V_RESn", "vol_res_n", XYZ),
    Alias("V_BACKp", "vol_back_p", XYZ),
    Alias("V_BACKn", "vol_back_n", XYZ),
    Alias("V_GYRO1", "vol_gyro_1", XYZ),
    Alias("V_GYRO2", "vol_gyro_2", XYZ),
    Alias("V_ACCp", "vol_acc_p", XYZ),
    Alias("V_ACCn", "vol_acc_n", XYZ),
    Alias("V_BLOCK", "vol_block", XYZ),
    Alias("V_BACK", "vol_back", XYZ),
    Alias("V_SERVO", "vol_srvo", XYZ),
    Alias("V_CABT", "vol_cabt", XYZ),
    Alias("V_FAN", "vol_fan", XYZ),
    # MagNav.jl's older HDF5 names
    Alias("tie_line", "line", MAGNAV_OLD),
    Alias("utmX", "utm_x", MAGNAV_OLD),
    Alias("utmY", "utm_y", MAGNAV_OLD),
    Alias("utmZ", "utm_z", MAGNAV_OLD),
    Alias("ins_azim", "ins_yaw", MAGNAV_OLD),
    Alias("pitch_rt", "pitch_rate", MAGNAV_OLD),
    Alias("roll_rt", "roll_rate", MAGNAV_OLD),
    Alias("yaw_rt", "yaw_rate", MAGNAV_OLD),
    Alias("lon_acc", "lgtl_acc", MAGNAV_OLD),
    Alias("lat_acc", "ltrl_acc", MAGNAV_OLD),
    Alias("alt_acc", "nrml_acc", MAGNAV_OLD),
    Alias("true_as", "tas", MAGNAV_OLD),
    Alias("vol_servo", "vol_srvo", MAGNAV_OLD),
    # MagNav.jl get_XYZ0: attitude without the ins_ prefix
    Alias("roll", "ins_roll", MAGNAV_XYZ0),
    Alias("pitch", "ins_pitch", MAGNAV_XYZ0),
    Alias("yaw", "ins_yaw", MAGNAV_XYZ0),
)

#: The SGL 2020 field names (MagNav.jl ``sgl_2020_fields_readme.txt``); SGL 2021 uses a subset.
_SGL_2020_TEXT = (
    "line flight year doy tt utm_x utm_y utm_z msl lat lon baro radar topo dem drape "
    "ins_pitch ins_roll ins_yaw diurnal mag_1_c mag_1_lag mag_1_dc mag_1_igrf mag_1_uc "
    "mag_2_uc mag_3_uc mag_4_uc mag_5_uc mag_6_uc "
    "flux_a_x flux_a_y flux_a_z flux_a_t flux_b_x flux_b_y flux_b_z flux_b_t "
    "flux_c_x flux_c_y flux_c_z flux_c_t flux_d_x flux_d_y flux_d_z flux_d_t ogs_mag ogs_alt "
    "ins_acc_x ins_acc_y ins_acc_z ins_wander ins_lat ins_lon ins_alt ins_vn ins_vw ins_vu "
    "pitch_rate roll_rate yaw_rate lgtl_acc ltrl_acc nrml_acc tas pitot_p static_p total_p "
    "cur_com_1 cur_ac_hi cur_ac_lo cur_tank cur_flap cur_strb cur_srvo_o cur_srvo_m cur_srvo_i "
    "cur_heat cur_acpwr cur_outpwr cur_bat_1 cur_bat_2 vol_acpwr vol_outpwr vol_bat_1 vol_bat_2 "
    "vol_res_p vol_res_n vol_back_p vol_back_n vol_gyro_1 vol_gyro_2 vol_acc_p vol_acc_n "
    "vol_block vol_back vol_srvo vol_cabt vol_fan"
)
SGL_2020_FIELDS: tuple[str, ...] = tuple(_SGL_2020_TEXT.split())

#: Our names beyond SGL's, and the numbered/lettered families of both.
EXTRA_FIELDS = ("alt", "maneuver")
_CANONICAL_FAMILIES = re.compile(
    r"^(mag_\d+_(uc|c|lag|dc|igrf)|flux_[a-z]_[xyzt]|(cur|vol|temp|truth)_\w+)$"
)
_CANONICAL = frozenset((*SGL_2020_FIELDS, *EXTRA_FIELDS))

ATTR = "aliases"
_PLACEHOLDERS = {"<n>": r"(?P<n>\d+)", "<s>": r"(?P<s>[A-Za-z])"}


def _pattern(original: str) -> re.Pattern[str]:
    """The regular expression of one table row (placeholders → groups), case-insensitive."""
    text = re.escape(original)
    for token, group in _PLACEHOLDERS.items():
        text = text.replace(re.escape(token), group)
    return re.compile(f"^{text}$", re.IGNORECASE)


_EXACT = {a.original.upper(): a.canonical for a in ALIASES if "<" not in a.original}
_PATTERNS = tuple((_pattern(a.original), a.canonical) for a in ALIASES if "<" in a.original)


def is_canonical(name: str) -> bool:
    """Whether ``name`` is one of our names (SGL 2020's, ``alt``, ``maneuver``, the families)."""
    return name in _CANONICAL or bool(_CANONICAL_FAMILIES.match(name))


def canonical_name(name: str) -> str:
    """Our name for a field name found in a file (``name`` itself when it has no alias).

    >>> canonical_name("UNCOMPMAG1"), canonical_name("utmZ"), canonical_name("TT")
    ('mag_1_uc', 'utm_z', 'tt')
    """
    if name in _CANONICAL:
        return name
    exact = _EXACT.get(name.upper())  # before the families: vol_servo is MagNav's vol_srvo
    if exact is not None:
        return exact
    for pattern, canonical in _PATTERNS:
        match = pattern.match(name)
        if match:
            groups = match.groupdict()
            if groups.get("n"):
                canonical = canonical.replace("<n>", str(int(groups["n"])))
            if groups.get("s"):
                canonical = canonical.replace("<s>", groups["s"].lower())
            return canonical
    if _CANONICAL_FAMILIES.match(name):
        return name
    folded = name.lower()
    return folded if is_canonical(folded) else name


def apply_aliases(
    fields: Mapping[str, np.ndarray], attrs: Mapping[str, Any]
) -> tuple[dict[str, np.ndarray], dict[str, Any], list[str]]:
    """Rename the fields that have an alias; never drop one, never rename silently.

    Parameters
    ----------
    fields : mapping of str to ndarray
        Fields under the names the file uses, in file order.
    attrs : mapping of str to Any
        File attributes; an existing ``aliases`` entry (a file written after an earlier
        renaming) is kept and extended.

    Returns
    -------
    fields : dict of str to ndarray
        Same order, canonical names where an alias applied.
    attrs : dict of str to Any
        With ``aliases`` = ``{canonical: original}`` when anything was renamed.
    notes : list of str
        One line listing the renamings, one line per name kept because of a clash.
    """
    present = set(fields)
    out: dict[str, np.ndarray] = {}
    renamed: dict[str, str] = {}
    notes: list[str] = []
    for name, values in fields.items():
        target = canonical_name(name)
        if target != name and target not in present and target not in renamed:
            out[target] = values
            renamed[target] = name
            continue
        out[name] = values
        if target != name:
            notes.append(_clash_note(name, target, renamed.get(target)))
    new_attrs = dict(attrs)
    if renamed:
        previous = attrs.get(ATTR)
        new_attrs[ATTR] = {**(previous if isinstance(previous, dict) else {}), **renamed}
        listed = ", ".join(f"{orig} → {canon}" for canon, orig in renamed.items())
        notes.insert(0, f"renamed by alias (attribute 'aliases' keeps the originals): {listed}")
    return out, new_attrs, notes


def _clash_note(name: str, target: str, first_alias: str | None) -> str:
    """The warning for an alias kept under its own name because ``target`` is taken."""
    if first_alias is None:
        return f"both {target} and its alias {name} present: kept {target}, and {name} as is"
    return (
        f"{first_alias} and {name} are both aliases of {target}: {first_alias} became "
        f"{target}, {name} kept as is"
    )


def alias_table_markdown() -> str:
    """The alias table as Markdown (for the README), one row per :data:`ALIASES` entry."""
    rows = ["| name in the file | our name | source |", "|---|---|---|"]
    rows += [f"| `{a.original}` | `{a.canonical}` | {a.source} |" for a in ALIASES]
    rows.append(
        "| any case variant of one of our names (`TT`, `LAT`, `DIURNAL`, …) | "
        "the name in lower case | all |"
    )
    return "\n".join(rows)
