"""The real rig's side: encoder drivers, robot sources, the durable capture, the virtual encoder
and the virtual ABB controller.

- :mod:`twin.hardware.encoders`: drawstring-encoder drivers behind one interface (ASCII and
  Modbus RTU over pyserial and minimalmodbus), the device URL and the settling rule;
- :mod:`twin.hardware.robot_sources`: where each captured pose's joint angles come from (the
  twin's robot, the operator, the controller's log, an ABB controller over RWS), one module
  per source and a registry;
- :mod:`twin.hardware.capture_request`: a capture as the command asks for it (robot, rig,
  source), then :mod:`twin.hardware.capture_session`: measure a pose plan pose by pose, each
  row on disk before the robot moves on, resumable after a crash;
- :mod:`twin.hardware.rws`: ABB Robot Web Services — the documented protocol, a client
  (requests), and a virtual controller (standard library) running the RAPID plan module;
- :mod:`twin.hardware.virtual_encoder`: the twin served on a pseudo-terminal as the real
  instrument would answer (pymodbus for Modbus); both virtual devices serve until a signal
  stops them (:mod:`twin.waiting`).

An adapter: the libraries of the extra ``hardware`` are imported only by the drivers, the RWS
client and the virtual encoder, when a command opens a device. This package imports nothing on
its own.
"""
