"""One module per flight-file format, each with its reader and writer, and the detection.

:mod:`.hdf5` (flat MagNav/SGL layout), :mod:`.csvfile`, :mod:`.xyz` (Geosoft XYZ), :mod:`.mat`
(MATLAB v5 and v7.3), :mod:`.detect` (the format from the content) and :mod:`.common` (what they
share). Readers return the fields under the file's own names; renaming to ours is
:mod:`aeromag_env.flight.aliases`' job, and validation :mod:`aeromag_env.flight.validation`'s.
"""
