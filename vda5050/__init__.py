"""VDA 5050 (2.0.0, 2.1.0, 3.0.0) as pure Python: no I/O, no Django, paho or Redis.

``models`` (typed messages, one shape for every version), ``versions`` (the versions we speak and the
3.0.0 wire translation), ``codec`` (bytes <-> models), ``topics`` (MQTT topic names), ``orders`` (building
and checking orders and instant actions), ``state`` (reading a robot's state), ``compat`` (vehicle
compatibility rules).
"""
