"""ABB Robot Web Services: the protocol as documented (:mod:`~twin.hardware.rws.protocol`),
a client (:mod:`~twin.hardware.rws.client`, over ``requests``), the server side of the
authentication (:mod:`~twin.hardware.rws.auth`) and a virtual controller
(:mod:`~twin.hardware.rws.virtual_controller`, standard library only)."""
