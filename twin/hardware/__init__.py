"""The real rig's side: encoder drivers, robot sources, the durable capture, the virtual encoder.

- :mod:`twin.hardware.encoders`: drawstring-encoder drivers behind one interface (ASCII and
  Modbus RTU over pyserial and minimalmodbus), the device URL and the settling rule;
- :mod:`twin.hardware.robot_sources`: where each captured pose's joint angles come from (the
  twin's robot, the operator, the controller's log);
- :mod:`twin.hardware.capture_session`: measure a pose plan pose by pose, each row on disk
  before the robot moves on, resumable after a crash;
- :mod:`twin.hardware.virtual_encoder`: the twin served on a pseudo-terminal as the real
  instrument would answer (pymodbus for Modbus).

An adapter: the libraries of the extra ``hardware`` are imported only by the drivers and the
virtual encoder, when a command opens a device. This package imports nothing on its own.
"""
