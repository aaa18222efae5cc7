"""The flight simulator: trajectory → Earth field → aircraft interference → sensors → Flight.

:mod:`.config` (the frozen configuration tree and presets), :mod:`.trajectory`,
:mod:`.interference` (paper eq. 5 and the 21-state layout), :mod:`.sensors`, :mod:`.effects` (extra
physics shared with discovery), :mod:`.auxiliary` (current/voltage/temperature channels) and
:mod:`.simulate` (all of them in order).
"""
