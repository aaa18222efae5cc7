"""Flight files: the in-memory flight, the readers and writers, and the checks on what they read.

:mod:`.data` (the :class:`~aeromag_env.flight.data.Flight` of named channels), :mod:`.files`
(read, write and convert; the format found from the content) over :mod:`.formats` (HDF5, CSV,
Geosoft XYZ, MATLAB .mat) and :mod:`.aliases` (other names for our fields, in one table),
:mod:`.validation` (what a tool can trust), :mod:`.quality` (time gaps and spikes),
:mod:`.mounting` (the fluxgate's mount), :mod:`.selection` (lines, segments, the calibration
line), :mod:`.info` (``aeromag info``) and :mod:`.plot` (the flight figure and the door to
matplotlib).
"""
