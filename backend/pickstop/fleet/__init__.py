"""Plans a fleet can run: VDA 5050 and Nav2 export, MQTT dispatch, simulated execution."""
