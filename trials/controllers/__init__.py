"""Robot controllers behind one interface, `Controller.plan(Observation) -> Plan`, found by name in `registry`."""
