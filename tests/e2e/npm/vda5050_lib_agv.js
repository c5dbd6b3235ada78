// A virtual AGV of npm vda-5050-lib (the version installed next to NODE_PATH), for tests/e2e/test_versions.py.
// Usage: node vda5050_lib_agv.js <mqtt url> <interfaceName> <manufacturer> <serialNumber>
// Runs until SIGTERM; states every second so that the fleet sees it online while it stands still.
const { AgvController, VirtualAgvAdapter } = require("vda-5050-lib");

const [brokerUrl, interfaceName, manufacturer, serialNumber] = process.argv.slice(2);
const agv = new AgvController(
    { manufacturer, serialNumber },
    { interfaceName, transport: { brokerUrl }, vdaVersion: "2.0.0" },
    { agvAdapterType: VirtualAgvAdapter, publishStateInterval: 1000 },
    { initialPosition: { mapId: "map", x: 0, y: 0, theta: 0, lastNodeId: "0" }, vehicleSpeed: 2 },
);
agv.start().then(() => console.log(`vda-5050-lib AGV ${serialNumber} started`));
process.on("SIGTERM", () => agv.stop().finally(() => process.exit(0)));
