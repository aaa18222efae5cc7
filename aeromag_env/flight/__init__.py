"""Flight files: the in-memory flight, the readers and writers, and the checks on what they read.

:mod:`.data` (the :class:`~aeromag_env.flight.data.Flight` of named channels), :mod:`.files`
(HDF5 and CSV in the flat MagNav/SGL layout), :mod:`.validation` (what a tool can trust),
:mod:`.info` (``aeromag info``) and :mod:`.plot` (the flight figure and the door to matplotlib).
"""
