"""The geophysical reference every stage shares: body/navigation frames and the Earth's field.

Flight files (plausibility checks, fluxgate mounting), the simulator and the compensator all
rotate between the body and the navigation frame (:mod:`.frames`) and evaluate the Earth's main
field along a track (:mod:`.earth`, IGRF-14 through ``ppigrf``), so these sit below all of them.
"""
