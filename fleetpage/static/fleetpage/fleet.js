// The live fleet page (/fleet): robots on a map per map_id, a robot's panel (its queue and its mission's
// tree), and the mission list, kept live by the server-sent events of GET /events. An event only records
// the object and marks it changed; once per animation frame the page redraws what changed (a marker moved,
// a row refilled), so a thousand robots moving cost a thousand marker moves per frame at most, never a
// redraw of everything per event.

const config = JSON.parse(document.getElementById("fleet-config").textContent);
const csrfToken = document.querySelector('meta[name="csrf-token"]').content;
const DEFAULT_MAP = ""; // the map of robots whose pose names none, shown as "default"
const LIST_ROWS = 200; // mission rows shown at most; the filters find the others
const CROWDED = 60; // more robots than this on the map shown: names only for the selected robot
const RECONNECT_MS = 5000; // after the server refused the stream (EventSource retries the rest itself)
const REFUSED = new Set([401, 403]); // a session that ended (or, for a write, a stale CSRF token)
const NOTICE_MS = 10000;
const DONE = new Set(config.done_states);
const NODE_FIELDS = new Set(["name", "parent"]); // a node's other non-null field is its kind

const robots = new Map(); // name -> robot, as GET /robot/{name} has it
const missions = new Map(); // name -> mission, as GET /mission/{name} has it; in the order first seen
const running = new Map(); // robot name -> the name of its RUNNING mission
const stations = new Map(); // name -> the station as the stream last sent it
const zoneSets = new Map(); // name -> the zone set as the stream last sent it
const zoneHolders = new Map(); // "map_id/zone_id" -> the robots holding that zone (their status.zone_access)
const changed = {
  robots: new Set(), missions: new Set(), missionRobots: new Set(), stations: new Set(), zoneSets: new Set(),
  maps: false, zoneHolders: false,
};
let frame = 0;
let received = null; // names sent since the stream (re)opened: after a snapshot, the others are gone
let snapshotDone = false;
let shownMap = null;
let fitPending = true;
let selected = null; // the robot whose panel is open
let queueOrder = []; // its queued missions in queue order, as GET /mission listed them
let shownTree = null; // {name, items: Map(node name -> <li>)} of the tree in the panel
let noticeTimer = 0;
let source = null; // the EventSource of GET /events
let sessionEnded = false; // the API refused the session: the page stops and asks for a login
let crowded = false; // more than CROWDED robots on the map shown

const $ = (id) => document.getElementById(id);

// --- the map ------------------------------------------------------------------------------------------

// CRS.Simple: one map unit is one of the robots' metres, y up.
const map = L.map("map", { crs: L.CRS.Simple, minZoom: -6, maxZoom: 7, zoomSnap: 0.25, attributionControl: false });
map.setView([0, 0], 4);
L.control.scale({ imperial: false }).addTo(map);
const Grid = L.GridLayer.extend({ createTile: gridTile });
new Grid({ tileSize: 256 }).addTo(map);
const markerLayer = L.layerGroup().addTo(map);
const markers = new Map(); // robot name -> L.Marker, for the robots on the map shown
const ROBOT_ICON = L.divIcon({
  className: "robot",
  iconSize: [22, 22],
  html: '<div class="robot-heading"></div><div class="robot-body"></div>' +
    '<div class="robot-battery"><span></span></div><div class="robot-name"></div>',
});

function gridTile(coords) {
  // Lines every 1, 2 or 5 x 10^k metres, at least 40 px apart at this zoom (2^z pixels per metre).
  const tile = document.createElement("canvas");
  const size = this.getTileSize();
  tile.width = size.x;
  tile.height = size.y;
  const scale = 2 ** coords.z;
  const decade = 10 ** Math.ceil(Math.log10(40 / scale));
  const step = [0.2, 0.5, 1].map((f) => f * decade).find((s) => s * scale >= 40) * scale;
  const context = tile.getContext("2d");
  context.strokeStyle = "#e3e8ee";
  context.beginPath();
  const left = coords.x * size.x;
  const top = coords.y * size.y;
  for (let x = Math.ceil(left / step) * step - left; x < size.x; x += step) {
    context.moveTo(Math.round(x) + 0.5, 0);
    context.lineTo(Math.round(x) + 0.5, size.y);
  }
  for (let y = Math.ceil(top / step) * step - top; y < size.y; y += step) {
    context.moveTo(0, Math.round(y) + 0.5);
    context.lineTo(size.x, Math.round(y) + 0.5);
  }
  context.stroke();
  return tile;
}

function mapOf(robot) {
  return robot.status.pose.map_id || DEFAULT_MAP;
}

function condition(robot) {
  const status = robot.status;
  if (!status.online) return "offline";
  if (Object.keys(status.errors ?? {}).length) return "error";
  if (status.state === "TELEOP") return "teleop";
  if (status.state === "CHARGING") return "charging";
  if (status.state === "ON_TASK") return "mission";
  return "idle";
}

function describe(robot) {
  const { pose, state, online, battery_level: battery } = robot.status;
  const degrees = Math.round((pose.theta * 180) / Math.PI);
  return `${robot.name}: ${state}, ${online ? "online" : "offline"}, battery ${Math.round(battery)}%, ` +
    `at (${pose.x.toFixed(2)}, ${pose.y.toFixed(2)}) heading ${degrees}°`;
}

function drawRobot(name) {
  const robot = robots.get(name);
  let marker = markers.get(name);
  if (!robot || mapOf(robot) !== shownMap) {
    if (marker) markerLayer.removeLayer(marker);
    markers.delete(name);
    return;
  }
  const { pose, battery_level: battery } = robot.status;
  const position = L.latLng(pose.y, pose.x);
  if (!marker) {
    marker = L.marker(position, { icon: ROBOT_ICON, keyboard: false }).on("click", () => select(name));
    markerLayer.addLayer(marker);
    markers.set(name, marker);
    const element = marker.getElement();
    element.dataset.robot = name;
    element.querySelector(".robot-name").textContent = name;
    marker.parts = {
      element,
      heading: element.querySelector(".robot-heading"),
      battery: element.querySelector(".robot-battery span"),
    };
    marker.looks = {};
  } else if (!marker.getLatLng().equals(position)) {
    marker.setLatLng(position);
  }
  const looks = {
    condition: condition(robot),
    title: describe(robot),
    selected: name === selected,
    heading: `rotate(${-pose.theta}rad)`,
    battery: `${Math.min(100, Math.max(0, battery))}%`,
  };
  for (const [look, value] of Object.entries(looks)) {
    // Only what changed: each write has the browser restyle the marker.
    if (marker.looks[look] !== value) LOOKS[look](marker.parts, value);
  }
  marker.looks = looks;
}

// How each look of a marker is drawn.
const LOOKS = {
  condition: (parts, value) => { parts.element.dataset.condition = value; },
  title: (parts, value) => { parts.element.title = value; },
  selected: (parts, value) => parts.element.classList.toggle("selected", value),
  heading: (parts, value) => { parts.heading.style.transform = value; },
  battery: (parts, value) => { parts.battery.style.width = value; },
};

// A station: a square in its kind's colour at its pose, under the robots; its tooltip says who holds it.
const stationLayer = L.layerGroup().addTo(map);
const stationMarkers = new Map(); // station name -> L.Marker, for the stations on the map shown

function drawStation(name) {
  const station = stations.get(name);
  let marker = stationMarkers.get(name);
  if (!station || (station.pose.map_id || DEFAULT_MAP) !== shownMap) {
    if (marker) stationLayer.removeLayer(marker);
    stationMarkers.delete(name);
    return;
  }
  const position = L.latLng(station.pose.y, station.pose.x);
  if (!marker) {
    const icon = L.divIcon({ className: "station", iconSize: [26, 26], html: '<div class="station-name"></div>' });
    marker = L.marker(position, { icon, keyboard: false, interactive: false, zIndexOffset: -1000 });
    stationLayer.addLayer(marker);
    stationMarkers.set(name, marker);
    marker.getElement().dataset.station = name;
    marker.getElement().querySelector(".station-name").textContent = name;
  } else if (!marker.getLatLng().equals(position)) {
    marker.setLatLng(position);
  }
  const { reservations } = station.status;
  const element = marker.getElement();
  element.dataset.kind = station.kind;
  element.dataset.held = reservations.length ? "yes" : "no";
  element.title = `${name}: ${station.kind}, ${reservations.length}/${station.capacity} held` +
    (reservations.length ? ` by ${reservations.join(", ")}` : "");
}

// The enabled zone sets of the map shown: each zone a polygon in its type's colour, under the stations. A zone
// a robot holds (its status.zone_access) is filled, and its tooltip names the robots.
const zoneLayer = L.layerGroup().addTo(map);
const zonePolygons = new Map(); // zone set name -> its zones' L.Polygons, for the enabled sets on the map shown

function drawZoneSet(name) {
  const zoneSet = zoneSets.get(name);
  for (const polygon of zonePolygons.get(name) ?? []) zoneLayer.removeLayer(polygon);
  zonePolygons.delete(name);
  if (!zoneSet || !zoneSet.status.enabled || (zoneSet.map_id || DEFAULT_MAP) !== shownMap) return;
  const polygons = zoneSet.zones.map((zone) => {
    const holders = zoneHolders.get(`${zoneSet.map_id}/${zone.zone_id}`) ?? [];
    const polygon = L.polygon(zone.vertices.map((v) => [v.y, v.x]), {
      className: `zone zone-${zone.zone_type.toLowerCase()}${holders.length ? " zone-held" : ""}`,
      interactive: true,
    });
    const capacity = zone.capacity ? `, ${holders.length}/${zone.capacity} held` : "";
    polygon.bindTooltip(
      `${zone.zone_id} (${zone.zone_type}${capacity})` + (holders.length ? ` by ${holders.join(", ")}` : ""),
      { sticky: true },
    );
    zoneLayer.addLayer(polygon);
    polygon.getElement()?.setAttribute("data-zone", `${name}/${zone.zone_id}`);
    return polygon;
  });
  zonePolygons.set(name, polygons);
}

function updateMapChoice() {
  const counts = new Map();
  for (const robot of robots.values()) counts.set(mapOf(robot), (counts.get(mapOf(robot)) ?? 0) + 1);
  if (!counts.has(shownMap) && counts.size) {
    // None shown yet, or the robots left the one shown (robots come on the default map until they report
    // their pose): the map with the most robots.
    showMap([...counts].sort((a, b) => b[1] - a[1])[0][0]);
  }
  const choice = $("map-choice");
  const ids = [...counts.keys()].sort();
  choice.replaceChildren(...ids.map((id) => new Option(`${id || "default"} (${counts.get(id)})`, id)));
  choice.value = shownMap ?? "";
}

function showMap(id) {
  shownMap = id;
  markerLayer.clearLayers();
  markers.clear();
  stationLayer.clearLayers();
  stationMarkers.clear();
  zoneLayer.clearLayers();
  zonePolygons.clear();
  for (const name of zoneSets.keys()) drawZoneSet(name);
  for (const name of stations.keys()) drawStation(name);
  for (const name of robots.keys()) drawRobot(name);
  for (const name of robots.keys()) drawRoute(name);
  fitPending = true;
}

function fitRobots() {
  const points = [...markers.values()].map((marker) => marker.getLatLng());
  if (points.length) map.fitBounds(L.latLngBounds(points).pad(0.15), { maxZoom: 5 });
}

// --- routes -----------------------------------------------------------------------------------------------

// The route of each robot's running mission on the map shown (when crowded: the selected robot's only): its
// waypoints as dots, the part driven in grey, the part still to drive in the mission colour, split at the
// robot. The robots report no VDA 5050 node ids through the API, so which waypoints of the running route
// the robot has passed is the page's estimate (`passedOf`); those of finished routes are passed, those of
// routes to come are not.
const routeLayer = L.layerGroup().addTo(map);
const shownRoutes = new Map(); // robot name -> {mission, driven, ahead, dots (id -> dot), selected}: its layers
const progress = new Map(); // robot name -> {mission, origin, node, start, next}: how far it got, as seen

function drawRoute(name) {
  const robot = robots.get(name);
  const mission = missions.get(running.get(name));
  if (!mission) progress.delete(name);
  let shown = shownRoutes.get(name);
  if (shown && shown.mission !== mission?.name) {
    removeRoute(name);
    shown = undefined;
  }
  if (!robot || !mission || !markers.has(name) || (crowded && name !== selected)) {
    removeRoute(name);
    return;
  }
  const route = routeOf(robot, mission);
  if (!shown) {
    const line = (className) => L.polyline([], { className, interactive: false });
    shown = { mission: mission.name, driven: line("route-driven"), ahead: line("route-ahead"), dots: new Map() };
    for (const part of [shown.driven, shown.ahead]) {
      routeLayer.addLayer(part);
      part.getElement().dataset.robot = name;
      part.getElement().dataset.mission = mission.name;
    }
    shownRoutes.set(name, shown);
  }
  shown.driven.setLatLngs(route.driven);
  shown.ahead.setLatLngs(route.ahead);
  const ids = new Set();
  let added = false;
  for (const waypoint of route.waypoints) {
    ids.add(waypoint.id);
    let dot = shown.dots.get(waypoint.id);
    if (!dot) {
      dot = L.circleMarker(waypoint.at, { className: "route-waypoint", radius: 4, interactive: false });
      routeLayer.addLayer(dot);
      Object.assign(dot.getElement().dataset, { robot: name, mission: mission.name, waypoint: waypoint.id });
      shown.dots.set(waypoint.id, dot);
      added = true;
    } else if (!dot.getLatLng().equals(waypoint.at)) {
      dot.setLatLng(waypoint.at); // the route was updated
    }
    const data = dot.getElement().dataset;
    const looks = { x: `${waypoint.x}`, y: `${waypoint.y}`, progress: waypoint.passed ? "passed" : "ahead" };
    for (const [look, value] of Object.entries(looks)) {
      if (data[look] !== value) data[look] = value;
    }
  }
  for (const [id, dot] of shown.dots) {
    if (!ids.has(id)) {
      routeLayer.removeLayer(dot);
      shown.dots.delete(id);
    }
  }
  if (shown.selected !== (name === selected) || (shown.selected && added)) {
    // The selected robot's route stands out, drawn over the others.
    shown.selected = name === selected;
    for (const layer of [shown.driven, shown.ahead, ...shown.dots.values()]) {
      layer.getElement().classList.toggle("selected", shown.selected);
      if (shown.selected) layer.bringToFront();
    }
  }
}

function removeRoute(name) {
  const shown = shownRoutes.get(name);
  if (!shown) return;
  for (const layer of [shown.driven, shown.ahead, ...shown.dots.values()]) routeLayer.removeLayer(layer);
  shownRoutes.delete(name);
}

function routeOf(robot, mission) {
  // The lines (driven, ahead) and the waypoints of the mission's route legs, split where the robot is; only
  // the points on the map shown.
  const here = L.latLng(robot.status.pose.y, robot.status.pose.x);
  const legs = routeLegs(mission);
  let trail = progress.get(robot.name);
  if (trail?.mission !== mission.name) {
    // The driven line begins where the page first saw the robot on this mission, unless it had finished a
    // route by then (where it came from is not known).
    const begun = legs.some((leg) => leg.state === "COMPLETED");
    trail = { mission: mission.name, origin: begun ? null : here, node: null, start: null, next: 0 };
    progress.set(robot.name, trail);
  }
  const driven = trail.origin ? [trail.origin] : [];
  const ahead = [];
  const waypoints = [];
  for (const leg of legs) {
    const points = leg.waypoints.map((waypoint, index) => ({
      id: `${leg.name}.${index}`,
      x: waypoint.x,
      y: waypoint.y,
      at: L.latLng(waypoint.y, waypoint.x),
      map: waypoint.map_id || DEFAULT_MAP,
    }));
    let passed = leg.state === "COMPLETED" ? points.length : 0;
    if (leg.state === "RUNNING") passed = passedOf(trail, leg.name, points, here, driven.at(-1) ?? here);
    points.forEach((point, index) => {
      point.passed = index < passed;
      if (point.map !== shownMap) return;
      (point.passed ? driven : ahead).push(point.at);
      waypoints.push(point);
    });
  }
  return { driven: [...driven, here], ahead: [here, ...ahead], waypoints };
}

function routeLegs(mission) {
  // The mission's route nodes in the order the robot drives them (depth first, in mission_tree's order),
  // with their state and waypoints (as POST /mission/{name}/update left them). Left out: routes that failed
  // or were canceled, and pending ones under a composite that has finished (they will not run).
  const stateOf = (name) => mission.status.node_status[name]?.state ?? "PENDING";
  const children = new Map();
  for (const node of mission.mission_tree) {
    if (!children.has(node.parent)) children.set(node.parent, []);
    children.get(node.parent).push(node);
  }
  const legs = [];
  const visit = (parent, finished) => {
    for (const node of children.get(parent) ?? []) {
      const state = stateOf(node.name);
      if (node.route && (state === "COMPLETED" || state === "RUNNING" || (state === "PENDING" && !finished))) {
        const waypoints = (mission.update_nodes?.[node.name] ?? node.route).waypoints;
        legs.push({ name: node.name, state, waypoints });
      }
      visit(node.name, finished || DONE.has(state));
    }
  };
  visit("root", DONE.has(stateOf("root")));
  return legs;
}

function passedOf(trail, node, points, here, start) {
  // How many waypoints of its running route the robot has passed, estimated: it is on the leg it is nearest
  // to (from where the route started to the first waypoint, or from one waypoint to the next), and never
  // goes back. A waypoint counts as passed once the robot is nearer the leg after it.
  if (trail.node !== node) Object.assign(trail, { node, start, next: 0 });
  let nearest = Infinity;
  let next = Math.min(trail.next, points.length - 1);
  for (let index = next; index < points.length; index += 1) {
    const from = index === 0 ? trail.start : points[index - 1].at;
    const distance = distanceToLeg(here, from, points[index].at);
    if (distance < nearest) {
      nearest = distance;
      next = index;
    }
  }
  trail.next = next;
  return next;
}

function distanceToLeg(point, from, to) {
  // Metres from `point` to the straight line between `from` and `to` (x is lng, y is lat).
  const dx = to.lng - from.lng;
  const dy = to.lat - from.lat;
  const length2 = dx * dx + dy * dy;
  const projected = length2 ? ((point.lng - from.lng) * dx + (point.lat - from.lat) * dy) / length2 : 0;
  const along = Math.max(0, Math.min(1, projected));
  return Math.hypot(point.lng - from.lng - along * dx, point.lat - from.lat - along * dy);
}

// --- the stream -----------------------------------------------------------------------------------------

function connect() {
  if (sessionEnded) return;
  const url = new URL(config.events_url, location.href);
  url.searchParams.set("mission.most_recent", config.mission_snapshot);
  source = new EventSource(url);
  source.addEventListener("open", () => {
    received = { robot: new Set(), mission: new Set(), station: new Set(), zone_set: new Set() };
    showStream("live");
  });
  source.addEventListener("robot", (event) => receive("robot", JSON.parse(event.data)));
  source.addEventListener("mission", (event) => receive("mission", JSON.parse(event.data)));
  source.addEventListener("station", (event) => receive("station", JSON.parse(event.data)));
  source.addEventListener("zone_set", (event) => receive("zone_set", JSON.parse(event.data)));
  source.addEventListener("snapshot_end", () => {
    forgetUnsent();
    snapshotDone = true;
    scheduleFrame();
  });
  source.addEventListener("error", (event) => {
    if (event.data) {
      // The server's error event, which ends the stream; EventSource then reconnects by itself.
      const { error, detail } = JSON.parse(event.data);
      notify(`Stream: ${error}: ${detail}`, true);
    } else if (source.readyState === EventSource.CLOSED) {
      // Refused (not a 200 event stream): EventSource gives up. Unless the session ended, the page tries
      // again a while later.
      showStream("down");
      sessionAlive().then((alive) => {
        if (alive) setTimeout(connect, RECONNECT_MS);
      });
    } else {
      showStream("reconnecting");
    }
  });
}

async function sessionAlive() {
  // EventSource does not say why the server refused it, nor does a write's 403 say whether the session or
  // only its CSRF token is stale: a list of no missions does. A page whose session ended stops (no retries)
  // and asks for a new login.
  if (sessionEnded) return false;
  const url = new URL(config.mission_list_url, location.href);
  url.searchParams.set("most_recent", 0);
  try {
    const response = await fetch(url, { credentials: "same-origin" });
    if (!REFUSED.has(response.status)) return true;
  } catch {
    return true; // the server is away, not the session
  }
  endSession();
  return false;
}

function endSession() {
  if (sessionEnded) return;
  sessionEnded = true;
  source?.close();
  showStream("ended");
  $("session-ended").hidden = false;
}

function showStream(state) {
  $("stream").dataset.stream = state;
  $("stream").textContent = state;
}

function receive(kind, object) {
  received?.[kind].add(object.name);
  const deleted = object.lifecycle === "DELETED";
  if (kind === "robot") {
    const before = robots.get(object.name);
    if (!before || deleted || mapOf(before) !== mapOf(object)) changed.maps = true;
    const held = (robot) => JSON.stringify(robot?.status?.zone_access?.held ?? []);
    if (held(before) !== (deleted ? "[]" : held(object))) changed.zoneHolders = true;
    deleted ? robots.delete(object.name) : robots.set(object.name, object);
    changed.robots.add(object.name);
  } else if (kind === "station") {
    deleted ? stations.delete(object.name) : stations.set(object.name, object);
    changed.stations.add(object.name);
  } else if (kind === "zone_set") {
    deleted ? zoneSets.delete(object.name) : zoneSets.set(object.name, object);
    changed.zoneSets.add(object.name);
  } else {
    // A mission given back to assignment leaves its robot (robot null): that robot is redrawn too.
    const robotBefore = missions.get(object.name)?.robot ?? null;
    deleted ? missions.delete(object.name) : missions.set(object.name, object);
    for (const robot of new Set([robotBefore, object.robot])) {
      if (robot === null) continue;
      if (running.get(robot) === object.name) running.delete(robot);
      changed.missionRobots.add(robot);
    }
    if (!deleted && object.status.state === "RUNNING") running.set(object.robot, object.name);
    changed.missions.add(object.name);
  }
  scheduleFrame();
}

function forgetUnsent() {
  // A snapshot names every object there is: the ones it left out were deleted while the page was away.
  for (const [name, robot] of robots) {
    if (!received.robot.has(name)) receive("robot", { ...robot, lifecycle: "DELETED" });
  }
  for (const [name, mission] of missions) {
    if (!received.mission.has(name)) receive("mission", { ...mission, lifecycle: "DELETED" });
  }
  for (const [name, station] of stations) {
    if (!received.station.has(name)) receive("station", { ...station, lifecycle: "DELETED" });
  }
  for (const [name, zoneSet] of zoneSets) {
    if (!received.zone_set.has(name)) receive("zone_set", { ...zoneSet, lifecycle: "DELETED" });
  }
}

function trimMissions() {
  // The page keeps as many missions as its snapshot had at most: finished ones go first, oldest first.
  let excess = missions.size - config.mission_snapshot;
  for (const [name, mission] of missions) {
    if (excess <= 0) return;
    if (DONE.has(mission.status.state)) {
      missions.delete(name);
      changed.missions.add(name);
      excess -= 1;
    }
  }
}

function scheduleFrame() {
  if (!frame) frame = requestAnimationFrame(flush);
}

function flush() {
  frame = 0;
  trimMissions();
  if (changed.maps) updateMapChoice();
  if (changed.zoneHolders) {
    updateZoneHolders();
    for (const name of zoneSets.keys()) changed.zoneSets.add(name);
  }
  for (const name of changed.zoneSets) drawZoneSet(name);
  for (const name of changed.stations) drawStation(name);
  for (const name of changed.robots) drawRobot(name);
  if (fitPending && snapshotDone && markers.size) {
    fitRobots();
    fitPending = false;
  }
  if (crowded !== markers.size > CROWDED) {
    crowded = !crowded;
    $("map").classList.toggle("crowded", crowded);
    for (const name of robots.keys()) drawRoute(name);
  }
  for (const name of new Set([...changed.robots, ...changed.missionRobots])) drawRoute(name);
  if (changed.missions.size || changed.list) drawMissionList();
  if (selected && (changed.panel || changed.robots.has(selected) || changed.missionRobots.has(selected))) {
    drawPanel();
  }
  drawCounts();
  changed.robots.clear();
  changed.missions.clear();
  changed.missionRobots.clear();
  changed.stations.clear();
  changed.zoneSets.clear();
  changed.maps = changed.list = changed.panel = changed.zoneHolders = false;
}

function updateZoneHolders() {
  zoneHolders.clear();
  for (const [name, robot] of robots) {
    for (const zone of robot.status.zone_access?.held ?? []) {
      const key = `${zone.map_id}/${zone.zone_id}`;
      zoneHolders.set(key, [...(zoneHolders.get(key) ?? []), name]);
    }
  }
}

function drawCounts() {
  let online = 0;
  for (const robot of robots.values()) online += robot.status.online ? 1 : 0;
  $("counts").textContent = `${robots.size} robots, ${online} online · ${missions.size} missions`;
}

// --- the mission list -------------------------------------------------------------------------------------

const rows = new Map(); // mission name -> its <tr>
const UNBOUND = "(unbound)"; // a mission's robot until assignment binds it (its waiting reason: the state's title)

function missionShown(mission) {
  const state = $("filter-state").value;
  const robot = $("filter-robot").value.trim().toLowerCase();
  const name = $("filter-name").value.trim().toLowerCase();
  return (!state || mission.status.state === state) &&
    (!robot || (mission.robot ?? UNBOUND).toLowerCase().includes(robot)) &&
    (!name || mission.name.toLowerCase().includes(name));
}

function newestFirst(missionList) {
  // As GET /mission?most_recent has them: not started first, then by start time, newest first.
  const started = (mission) => (mission.status.start_timestamp ? Date.parse(mission.status.start_timestamp) : Infinity);
  return missionList
    .map((mission) => [started(mission), mission])
    .sort((a, b) => (b[0] > a[0]) - (b[0] < a[0]))
    .map(([, mission]) => mission);
}

function drawMissionList() {
  const shown = newestFirst([...missions.values()].filter(missionShown));
  const visible = shown.slice(0, LIST_ROWS);
  const names = new Set(visible.map((mission) => mission.name));
  for (const [name, row] of rows) {
    if (!names.has(name)) {
      row.remove();
      rows.delete(name);
    }
  }
  const body = $("mission-rows");
  let previous = null;
  for (const mission of visible) {
    let row = rows.get(mission.name);
    if (!row) {
      row = missionRow(mission.name);
      rows.set(mission.name, row);
      fillMissionRow(row, mission);
    } else if (changed.missions.has(mission.name)) {
      fillMissionRow(row, mission);
    }
    const there = previous ? previous.nextElementSibling : body.firstElementChild;
    if (there !== row) (previous ? previous.after(row) : body.prepend(row));
    previous = row;
  }
  $("mission-count").textContent = shown.length > visible.length ? `${visible.length} of ${shown.length}` : `${shown.length}`;
}

function missionRow(name) {
  const row = document.createElement("tr");
  row.dataset.mission = name;
  row.innerHTML = '<td class="name"></td><td><button type="button" class="link robot-link"></button></td>' +
    '<td><span class="state"></span></td><td class="node"></td><td class="started"></td>' +
    '<td><button type="button" class="cancel">Cancel</button></td>';
  row.querySelector(".name").textContent = name;
  return row;
}

function fillMissionRow(row, mission) {
  const { state, current_node: current, start_timestamp: started, failure_reason: failure } = mission.status;
  row.dataset.state = state;
  // A mission posted without a robot shows "(unbound)" until assignment binds it, then who took it.
  row.querySelector(".robot-link").textContent = mission.robot ?? UNBOUND;
  row.querySelector(".robot-link").disabled = mission.robot === null;
  row.querySelector(".state").textContent = state;
  row.querySelector(".state").dataset.state = state;
  row.querySelector(".state").title = failure ?? mission.status.waiting_reason ?? "";
  row.querySelector(".node").textContent = mission.mission_tree[current]?.name ?? "";
  row.querySelector(".started").textContent = started ? new Date(started).toLocaleTimeString([], { hourCycle: "h23" }) : "";
  row.querySelector(".cancel").hidden = DONE.has(state);
}

// --- the robot's panel ------------------------------------------------------------------------------------

async function select(name) {
  const previous = selected;
  selected = name;
  queueOrder = [];
  shownTree = null;
  $("robot-panel").hidden = name === null;
  if (previous) {
    drawRobot(previous);
    drawRoute(previous);
  }
  if (name === null) return;
  drawRobot(name);
  drawRoute(name);
  changed.panel = true;
  scheduleFrame();
  const url = new URL(config.mission_list_url, location.href);
  url.search = new URLSearchParams({ robot: name, state: "PENDING" });
  const response = await fetch(url, { credentials: "same-origin" });
  if (REFUSED.has(response.status)) sessionAlive();
  if (response.ok && selected === name) {
    queueOrder = (await response.json()).map((mission) => mission.name);
    changed.panel = true;
    scheduleFrame();
  }
}

function drawPanel() {
  const robot = robots.get(selected);
  $("robot-name").textContent = selected;
  if (!robot) {
    $("robot-facts").replaceChildren(fact("Robot", "deleted"));
    return;
  }
  const { state, online, battery_level: battery, pose, errors } = robot.status;
  $("robot-facts").replaceChildren(
    fact("State", `${state} (${condition(robot)})`),
    fact("Online", online ? "yes" : "no"),
    fact("Battery", `${Math.round(battery)}%`),
    fact("Pose", `(${pose.x.toFixed(2)}, ${pose.y.toFixed(2)}), ${Math.round((pose.theta * 180) / Math.PI)}°, map ${pose.map_id || "default"}`),
    fact("Teleop", robot.switch_teleop ? "requested" : "off"),
    fact("Errors", Object.keys(errors ?? {}).join(", ") || "none"),
  );
  const own = [...missions.values()].filter((mission) => mission.robot === selected);
  const queuePlace = (mission) => {
    const place = queueOrder.indexOf(mission.name);
    return place < 0 ? Infinity : place;
  };
  const queue = [
    ...own.filter((mission) => mission.status.state === "RUNNING"),
    ...own.filter((mission) => mission.status.state === "PENDING").sort((a, b) => queuePlace(a) - queuePlace(b) || 0),
  ];
  $("robot-queue").replaceChildren(...queue.map(queueItem));
  const latest = newestFirst(own.filter((mission) => mission.status.start_timestamp))[0];
  drawTree(queue[0]?.status.state === "RUNNING" ? queue[0] : latest);
}

function fact(term, value) {
  const row = document.createElement("div");
  const dt = document.createElement("dt");
  const dd = document.createElement("dd");
  dt.textContent = term;
  dd.textContent = value;
  row.append(dt, dd);
  return row;
}

function queueItem(mission) {
  const item = document.createElement("li");
  item.dataset.mission = mission.name;
  item.dataset.state = mission.status.state;
  item.textContent = `${mission.name} ${mission.status.state}`;
  if (mission.status.waiting_reason) item.title = mission.status.waiting_reason;
  const cancel = document.createElement("button");
  cancel.type = "button";
  cancel.className = "cancel";
  cancel.textContent = "Cancel";
  item.append(" ", cancel);
  return item;
}

function drawTree(mission) {
  if (!mission) {
    shownTree = null;
    $("tree-title").textContent = "Mission tree";
    $("robot-tree").replaceChildren();
    return;
  }
  if (shownTree?.name !== mission.name) shownTree = { name: mission.name, items: buildTree(mission) };
  const { state, node_status: nodes, current_node: current } = mission.status;
  $("tree-title").textContent = `Mission ${mission.name}: ${state}`;
  const currentName = state === "RUNNING" ? mission.mission_tree[current]?.name : undefined;
  for (const [name, item] of shownTree.items) {
    const status = nodes[name] ?? { state: "PENDING", error_msg: null };
    item.dataset.state = status.state;
    item.querySelector(":scope > .node-state").textContent = status.state;
    item.title = status.error_msg ?? "";
    item.classList.toggle("current", name === currentName);
  }
}

function buildTree(mission) {
  // The tree as nested lists: "root" first, each node under its parent, in mission_tree's order.
  const items = new Map();
  const nodeItem = (name, kind) => {
    const item = document.createElement("li");
    item.dataset.node = name;
    item.innerHTML = '<span class="node-state"></span> <span class="node-name"></span> <span class="node-kind"></span>';
    item.querySelector(".node-name").textContent = name;
    item.querySelector(".node-kind").textContent = kind;
    items.set(name, item);
    return item;
  };
  const root = document.createElement("ul");
  root.append(nodeItem("root", "sequence"));
  for (const node of mission.mission_tree) {
    const kind = Object.keys(node).find((key) => !NODE_FIELDS.has(key) && node[key] !== null);
    const parent = items.get(node.parent);
    let children = parent.querySelector(":scope > ul");
    if (!children) children = parent.appendChild(document.createElement("ul"));
    children.append(nodeItem(node.name, kind));
  }
  $("robot-tree").replaceChildren(root);
  return items;
}

// --- operator actions, through the REST API with the session --------------------------------------------

function fill(template, name) {
  return template.replace(config.name_placeholder, encodeURIComponent(name));
}

async function act(url, what) {
  try {
    const response = await fetch(url, { method: "POST", headers: { "X-CSRFToken": csrfToken }, credentials: "same-origin" });
    if (REFUSED.has(response.status) && !(await sessionAlive())) return;
    if (!response.ok) throw new Error(apiError(await response.json().catch(() => null), response.status));
    notify(`${what}: done`);
  } catch (error) {
    notify(`${what} failed: ${error.message}`, true);
  }
}

function apiError(body, status) {
  // The API's three error bodies (README, "REST API"): a usage error, a missing object, schema errors.
  if (body?.message) return body.message;
  if (typeof body?.detail === "string") return body.detail;
  if (Array.isArray(body?.detail)) return body.detail.map((error) => error.msg).join("; ");
  return `HTTP ${status}`;
}

function cancelMission(name) {
  if (confirm(`Cancel mission ${name}?`)) act(fill(config.mission_cancel_url, name), `Cancel ${name}`);
}

function teleop(params) {
  const url = new URL(fill(config.robot_teleop_url, selected), location.href);
  url.searchParams.set("params", params);
  act(url, `Teleop ${params} for ${selected}`);
}

function notify(text, failed = false) {
  $("notice").textContent = text;
  $("notice").classList.toggle("failed", failed);
  clearTimeout(noticeTimer);
  noticeTimer = setTimeout(() => { $("notice").textContent = ""; }, NOTICE_MS);
}

// --- wiring -----------------------------------------------------------------------------------------------

function listChanged() {
  changed.list = true;
  scheduleFrame();
}

function onMissionButton(event) {
  const button = event.target.closest("button");
  const mission = button?.closest("[data-mission]")?.dataset.mission;
  if (!mission) return;
  if (button.classList.contains("cancel")) cancelMission(mission);
  else if (button.classList.contains("robot-link")) select(missions.get(mission)?.robot ?? null);
}

for (const state of config.mission_states) $("filter-state").append(new Option(state, state));
for (const id of ["filter-state", "filter-robot", "filter-name"]) $(id).addEventListener("input", listChanged);
$("mission-rows").addEventListener("click", onMissionButton);
$("robot-queue").addEventListener("click", onMissionButton);
$("map-choice").addEventListener("change", (event) => {
  showMap(event.target.value);
  scheduleFrame();
});
$("fit").addEventListener("click", fitRobots);
$("robot-close").addEventListener("click", () => select(null));
$("teleop-start").addEventListener("click", () => teleop("START"));
$("teleop-stop").addEventListener("click", () => teleop("STOP"));
connect();
