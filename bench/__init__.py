"""Load generator and report for Mission Dispatch: fast fake VDA 5050 robots, missions over the REST API."""
