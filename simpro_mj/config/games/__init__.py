"""Games' motion telemetry packets, one module per format, each decoding to ISO 8855.

Every decoder returns one sample ``(time_s, f, w)``: the specific force
``f = a - g`` (gravity included, ``+9.81`` on z at rest) and the angular
velocity ``w`` in the vehicle frame V of ISO 8855 (x forward, y left, z up),
SI; ``time_s`` is the game's clock, or ``None`` where the packet carries none
(the receiver then orders by arrival). Each module also packs a V-frame
sample into its packet (``encode``), for ``simpro-sim send`` and the tests.

The conversion to V is done once, in the module that reads the packet; the
readings chosen where a game's documentation leaves a sign open are stated
in the module, with the alternative.
"""
