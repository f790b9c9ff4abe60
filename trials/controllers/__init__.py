"""Robot controllers behind one interface: `Controller.plan(Observation) -> Plan`."""
