"""The jobs a user runs, one library function each, in a room named after the job; the command
line (:mod:`aeromag_env.cli`) parses its arguments, calls one of them and prints.

* simulate a flight: :func:`~aeromag_env.jobs.simulate.simulate` (``aeromag simulate``)
* inspect a file: :func:`~aeromag_env.jobs.info.info` (``aeromag info``)
* convert a file: :func:`~aeromag_env.jobs.convert.convert` (``aeromag convert``)
* a sample survey file: :func:`~aeromag_env.jobs.example.example` (``aeromag example``)
* fit a model on a calibration flight: :func:`~aeromag_env.jobs.calibrate.calibrate`
  (``aeromag calibrate``)
* compensate a flight, or apply a model: :func:`~aeromag_env.jobs.compensate.compensate`
  (``aeromag compensate``, ``--model``)
* compensate samples as they arrive: :func:`~aeromag_env.jobs.stream.stream` (``aeromag
  stream``)
* a fleet of flights: :func:`~aeromag_env.jobs.fleet.fleet` (``aeromag compensate DIR``)
* find a missing effect: :func:`~aeromag_env.jobs.discover.discover` (``aeromag discover``)
* the paper's figures: :func:`~aeromag_env.jobs.reproduce.reproduce` (``aeromag
  reproduce-paper``)
* evaluate tuners: :func:`~aeromag_env.jobs.evaluate.evaluate` (``aeromag evaluate``)
* train a tuner: :func:`~aeromag_env.jobs.train.train` (``aeromag train``)
* search hyperparameters: :func:`~aeromag_env.jobs.tune.tune` (``aeromag tune``)
* the demo: :func:`~aeromag_env.jobs.demo.demo` (``aeromag demo``)
* the speed benchmark: :func:`~aeromag_env.jobs.bench.bench` (``aeromag bench``)

Each validates its arguments before any work (:mod:`aeromag_env.jobs.limits`: one
:class:`~aeromag_env.errors.ArgumentError` naming the argument, which the command line re-spells
as its option), does everything the command line does (reading, choosing channels and mounts,
provenance, writing the output set atomically) and returns a typed result; its warnings are
issued as :class:`~aeromag_env.errors.AeromagWarning` and kept in the result. The jobs are the
top layer of the library: they import ``agents`` and everything below; only the command line
imports them.

This package's face exposes the error types the command line catches (importing it loads
nothing else); :mod:`aeromag_env.jobs.choices` the values the arguments choose among.
"""

from aeromag_env.errors import AeromagError, AeromagWarning, ArgumentError

__all__ = ["AeromagError", "AeromagWarning", "ArgumentError"]
