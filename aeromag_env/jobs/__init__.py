"""The jobs a user runs, one library function each: what ``aeromag compensate``, ``aeromag
discover`` and their fleet form do, from a flight file (or a :class:`~aeromag_env.flight.data.
Flight`) to a typed result and, when asked, the output set on disk.

* :func:`aeromag_env.jobs.compensate.compensate` → :class:`~aeromag_env.jobs.compensate.
  CompensationResult`
* :func:`aeromag_env.jobs.discover.discover` → :class:`~aeromag_env.jobs.discover.DiscoverResult`
* :func:`aeromag_env.jobs.fleet.fleet` → :class:`~aeromag_env.jobs.fleet.FleetResult`

Each does everything the command line does (choosing the channels, estimating the fluxgate
mount, flagging gaps and spikes, provenance, the report, writing the output set atomically); the
command line (:mod:`aeromag_env.cli`) parses its arguments, calls one of them and prints. Their
warnings are issued as :class:`~aeromag_env.errors.AeromagWarning` and returned in the result's
``warnings``. The package's top level (``aeromag_env.compensate``…) resolves to these.
"""
