// Pure helpers for scene documents: JSON merge patches (RFC 7396), JSON pointers (RFC 6901),
// orbit math and colour conversion. No DOM access here.

export const isObject = (v) => v !== null && typeof v === 'object' && !Array.isArray(v);

export const deepClone = (v) => (v === undefined ? undefined : JSON.parse(JSON.stringify(v)));

export function deepEqual(a, b) {
  if (a === b) return true;
  if (typeof a !== typeof b || a === null || b === null || typeof a !== 'object') return false;
  if (Array.isArray(a) !== Array.isArray(b)) return false;
  const ka = Object.keys(a);
  const kb = Object.keys(b);
  if (ka.length !== kb.length) return false;
  return ka.every((k) => Object.prototype.hasOwnProperty.call(b, k) && deepEqual(a[k], b[k]));
}

// Applies merge patch `patch` to `target`; neither argument is modified.
export function applyMergePatch(target, patch) {
  if (!isObject(patch)) return deepClone(patch);
  const out = isObject(target) ? { ...target } : {};
  for (const [key, value] of Object.entries(patch)) {
    if (value === null) delete out[key];
    else out[key] = applyMergePatch(out[key], value);
  }
  return out;
}

// One merge patch with the effect of applying `first` and then `second` (nulls remove whole lights, which
// are added back whole, so merging into a removed member does not arise).
export function composePatches(first, second) {
  if (!first) return deepClone(second);
  if (!second) return deepClone(first);
  if (!isObject(first) || !isObject(second)) return deepClone(second);
  const out = { ...first };
  for (const [key, value] of Object.entries(second)) {
    out[key] = isObject(value) && isObject(out[key]) ? composePatches(out[key], value) : deepClone(value);
  }
  return out;
}

// Drops every leaf of `patch` that already has that value in `base` (a null, a removal, is kept only where
// `base` has the member); returns null when nothing is left.
export function prunePatch(base, patch) {
  if (!isObject(patch)) return deepEqual(base, patch) ? null : deepClone(patch);
  const out = {};
  for (const [key, value] of Object.entries(patch)) {
    const baseValue = isObject(base) ? base[key] : undefined;
    if (value === null) {
      if (baseValue !== undefined) out[key] = null;
      continue;
    }
    const kept = isObject(value) && isObject(baseValue) ? prunePatch(baseValue, value)
      : deepEqual(baseValue, value) ? null : deepClone(value);
    if (kept !== null) out[key] = kept;
  }
  return Object.keys(out).length ? out : null;
}

export function parsePointer(pointer) {
  if (!pointer || pointer === '/') return [];
  return pointer.replace(/^\//, '').split('/').map((t) => t.replace(/~1/g, '/').replace(/~0/g, '~'));
}

export function getAt(doc, pointer) {
  let node = doc;
  for (const token of parsePointer(pointer)) {
    if (node === null || typeof node !== 'object') return undefined;
    node = node[token];
  }
  return node;
}

// A merge patch that sets `pointer` to `value` (pointers into arrays are not allowed: arrays are
// replaced whole by merge patches, so controls always write the entire array).
export function patchAt(pointer, value) {
  const tokens = parsePointer(pointer);
  let patch = deepClone(value);
  for (let i = tokens.length - 1; i >= 0; --i) patch = { [tokens[i]]: patch };
  return patch;
}

// Whether `patch` writes the value at `pointer` or anything containing or inside it.
export function patchTouches(patch, pointer) {
  let node = patch;
  for (const token of parsePointer(pointer)) {
    if (!isObject(node)) return true;  // an array or scalar written whole covers everything below it
    if (!(token in node)) return false;
    node = node[token];
  }
  return true;
}

// `patch` without whatever it writes at or below `pointer` (a leaf array containing the pointer is
// removed whole); empty parents are pruned. Returns null when nothing is left.
export function removeFromPatch(patch, pointer) {
  const tokens = parsePointer(pointer);
  const walk = (node, i) => {
    if (i >= tokens.length || !isObject(node)) return null;
    if (!(tokens[i] in node)) return node;
    const out = { ...node };
    const child = walk(node[tokens[i]], i + 1);
    if (child === null) delete out[tokens[i]];
    else out[tokens[i]] = child;
    return Object.keys(out).length ? out : null;
  };
  return walk(deepClone(patch), 0);
}

// A merge patch that turns `current` into `target`: members `target` lacks are deleted (null: the daemon
// restores their defaults), the rest set where they differ. Null when nothing differs.
export function replacementPatch(current, target) {
  if (!isObject(current) || !isObject(target)) return deepEqual(current, target) ? null : deepClone(target);
  const out = {};
  for (const key of Object.keys(current)) {
    if (!(key in target)) out[key] = null;
  }
  for (const [key, value] of Object.entries(target)) {
    if (value === null) {
      if (key in current) out[key] = null;
      continue;
    }
    const kept = replacementPatch(current[key], value);
    if (kept !== null) out[key] = kept;
  }
  return Object.keys(out).length ? out : null;
}

// ---- vectors and orbits --------------------------------------------------------------------------

export const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
export const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
export const scale = (a, s) => [a[0] * s, a[1] * s, a[2] * s];
export const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
export const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
export const length = (a) => Math.hypot(a[0], a[1], a[2]);
export const normalize = (a) => { const l = length(a); return l > 0 ? scale(a, 1 / l) : [0, 0, 0]; };
export const round = (x, digits = 4) => { const f = 10 ** digits; return Math.round(x * f) / f || 0; };
export const roundVec = (a, digits = 4) => a.map((x) => round(x, digits));

const DEG = Math.PI / 180;
export const MAX_ELEVATION = 89 * DEG;

// Spherical coordinates of `point` around `center` (y up): radius, azimuth about +y from +z, elevation.
export function toSpherical(point, center) {
  const d = sub(point, center);
  const radius = length(d);
  if (radius < 1e-9) return { radius: 0, azimuth: 0, elevation: 0 };
  return { radius, azimuth: Math.atan2(d[0], d[2]), elevation: Math.asin(Math.max(-1, Math.min(1, d[1] / radius))) };
}

export function fromSpherical(center, { radius, azimuth, elevation }) {
  const c = Math.cos(elevation);
  return add(center, [radius * c * Math.sin(azimuth), radius * Math.sin(elevation), radius * c * Math.cos(azimuth)]);
}

// Rotates `point` around `center` by the given angle deltas (radians), keeping its distance.
export function orbit(point, center, dAzimuth, dElevation, fallbackRadius = 3) {
  const s = toSpherical(point, center);
  if (s.radius === 0) s.radius = fallbackRadius;
  s.azimuth += dAzimuth;
  s.elevation = Math.max(-MAX_ELEVATION, Math.min(MAX_ELEVATION, s.elevation + dElevation));
  return fromSpherical(center, s);
}

// Moves `point` towards/away from `center` by `factor`, clamped to [minR, maxR].
export function dolly(point, center, factor, minR = 0.05, maxR = 5000) {
  const s = toSpherical(point, center);
  s.radius = Math.max(minR, Math.min(maxR, (s.radius || 1) * factor));
  return fromSpherical(center, s);
}

// `v` turned by XYZ Euler angles in degrees, X first, then Y, then Z (as object.rotation_deg is applied).
export function rotateXYZ(v, deg) {
  const [x, y, z] = (deg || [0, 0, 0]).map((d) => d * DEG);
  let [a, b, c] = v;
  [b, c] = [b * Math.cos(x) - c * Math.sin(x), b * Math.sin(x) + c * Math.cos(x)];
  [a, c] = [a * Math.cos(y) + c * Math.sin(y), -a * Math.sin(y) + c * Math.cos(y)];
  [a, b] = [a * Math.cos(z) - b * Math.sin(z), a * Math.sin(z) + b * Math.cos(z)];
  return [a, b, c];
}

// Where an object's mesh, with bounds `{min, max}` in its own units, lies in the world: the centre and
// radius of a sphere around its placed bounding box (object.position, rotation_deg, scale applied), and
// that box's corners `lo` and `hi`.
export function placedBounds(bounds, object) {
  const s = object.scale ?? 1;
  const corners = [0, 1, 2, 3, 4, 5, 6, 7].map((k) => [0, 1, 2].map((i) => ((k >> i) & 1 ? bounds.max[i] : bounds.min[i])));
  const placed = corners.map((p) => add(object.position || [0, 0, 0], rotateXYZ(scale(p, s), object.rotation_deg)));
  const lo = [0, 1, 2].map((i) => Math.min(...placed.map((p) => p[i])));
  const hi = [0, 1, 2].map((i) => Math.max(...placed.map((p) => p[i])));
  const center = scale(add(lo, hi), 0.5);
  return { center, radius: Math.max(1e-6, ...placed.map((p) => length(sub(p, center)))), lo, hi };
}

// What frames a document's new members: its camera (cameraOf), the aspect of the frames it is seen in (a
// viewer's, which follow its viewport, not the document's image size) and its floor's height (-Infinity: none).
export function viewOf(doc, aspect) {
  return { camera: cameraOf(doc), aspect, floor: doc.floor?.enabled ? (doc.floor.height ?? -1) : -Infinity };
}

// Half the width of a level box of half-extents `half` across horizontal direction `d`.
const across = (half, d) => Math.abs(d[0]) * half[0] + Math.abs(d[2]) * half[2];
// The middle of the bottom face of a box `{min, max}`: what a thing stands on.
const footOf = (box) => [(box.min[0] + box.max[0]) / 2, box.min[1], (box.min[2] + box.max[2]) / 2];
const longestSide = (box) => Math.max(1e-9, ...[0, 1, 2].map((i) => box.max[i] - box.min[i]));
// A uniform scale as members take it: 4 significant digits, in (0, 1000].
const memberScale = (s) => Math.min(1000, Math.max(1e-6, Number(s.toPrecision(4))));

// Where a new member goes beside a placed one (`placedBounds` of it), seen in `view` (viewOf): the scale
// and position (unrotated) of a thing whose box in its own units is `box`. Its longest side is the placed
// one's largest half-extent, whatever units its file uses; it stands on the same bottom (or on the floor,
// where that is higher), just past it towards the view's right (horizontally), or its left. Where the
// whole box would not be in the frame, it is made smaller (and so nearer), so that it is seen wherever
// the camera looks from; failing that, the first spot. With `lit` (a point's light, lightAt), of the
// spots in the frame the one whose middle is lit most: a volume scatters only the light it gets.
export function besideObject(placed, box, view, lit = null) {
  const half = Math.max(1e-3, ...[0, 1, 2].map((i) => (placed.hi[i] - placed.lo[i]) / 2));
  const placedHalf = scale(sub(placed.hi, placed.lo), 0.5);
  const forward = sub(view.camera.target, view.camera.position);
  const flat = normalize([-forward[2], 0, forward[0]]);  // forward x up: the view's right, level
  const right = flat[0] || flat[2] ? flat : [1, 0, 0];
  const foot = footOf(box);
  const bottom = Math.max(placed.lo[1], view.floor ?? -Infinity);
  const spots = [];
  let best = null;
  for (const shrink of [1, 0.8, 0.64, 0.5, 0.4]) {
    for (const side of [right, scale(right, -1)]) {
      const s = memberScale((shrink * half) / longestSide(box));
      const own = scale(sub(box.max, box.min), s / 2);
      const gap = 0.1 * s * longestSide(box);  // a tenth of its longest side (0.2 of a new sphere's radius)
      const centre = add(placed.center, scale(side, across(placedHalf, side) + across(own, side) + gap));
      const position = roundVec([centre[0] - s * foot[0], bottom - s * foot[1], centre[2] - s * foot[2]], 4);
      const spot = { scale: s, position };
      spots.push(spot);
      const seen = placedBounds(box, spot);
      if (!inFrame(view, seen)) continue;
      if (!lit) return spot;
      const light = lit(seen.center);
      if (!best || light > best.light) best = { spot, light };
    }
  }
  return best ? best.spot : spots[0];
}

// A light member as the daemon fills it in (protocol/README.md, lights): its type, power (luminance),
// unit axis and position.
function lamp(light) {
  return {
    type: light.type ?? 'spot', power: luminance(light.color ?? [1, 1, 1]) * (light.intensity ?? 20),
    axis: normalize(light.direction ?? [-2, -3, -1]), position: light.position ?? [2, 3, 1],
  };
}

// The light (luminance, W/m^2 on a surface facing it) that reaches point `p` of `doc`: each spot's inside
// its cone, each point light's, by the inverse square, and the directional lights'; none of it where the
// straight way from the light crosses `blocker` (a ball {center, radius} an object fills), so that the
// side of an object in its own shadow counts as dark.
export function lightAt(doc, p, blocker = null) {
  const shadowed = (from, d, far) => {
    if (!blocker) return false;
    const t = Math.min(far, Math.max(0, dot(sub(blocker.center, from), d)));
    return length(sub(add(from, scale(d, t)), blocker.center)) < blocker.radius;
  };
  let total = 0;
  for (const light of Object.values(doc.lights || {})) {
    const { type, power, axis, position } = lamp(light);
    if (type === 'directional') {
      if (!shadowed(p, scale(axis, -1), Infinity)) total += power;
      continue;
    }
    const to = sub(p, position);
    const r = Math.max(1e-3, length(to));
    const d = scale(to, 1 / r);
    const cone = Math.cos(((light.cone_deg ?? 25) * Math.PI) / 180);
    if ((type === 'point' || dot(d, axis) >= cone) && !shadowed(position, d, r)) total += power / (r * r);
  }
  return total;
}

// Whether every corner of a placed box (`lo`, `hi`) is inside the frame of `view`, a little in from its edges.
function inFrame(view, { lo, hi }) {
  return [0, 1, 2, 3, 4, 5, 6, 7].every((k) => {
    const p = project(view.camera, view.aspect, [0, 1, 2].map((i) => ((k >> i) & 1 ? hi[i] : lo[i])));
    return p !== null && Math.abs(p.x) <= 0.95 && Math.abs(p.y) <= 0.95;
  });
}

// The scale and position that stand a thing of box `to` (its own units) where one of box `from` stands
// as `member` places it: the same bottom middle and longest side, its rotation kept. A volume that takes
// another file keeps its place and size so, whatever the new file's units and origin.
export function standInstead(from, to, member) {
  const before = member.scale ?? 1;
  const s = memberScale((before * longestSide(from)) / longestSide(to));
  const at = add(member.position || [0, 0, 0], rotateXYZ(scale(footOf(from), before), member.rotation_deg));
  return { scale: s, position: roundVec(sub(at, rotateXYZ(scale(footOf(to), s), member.rotation_deg)), 4) };
}

// Scale and position that fit a mesh with bounds `{min, max}` to `size` (its longest side) with its
// centre at the origin, for the given rotation.
export function fitObject(bounds, size, rotationDeg) {
  const extent = Math.max(...[0, 1, 2].map((i) => bounds.max[i] - bounds.min[i]));
  const s = extent > 0 ? Number((size / extent).toPrecision(4)) : 1;
  const center = scale(add(bounds.min, bounds.max), 0.5);
  return { scale: s, position: roundVec(scale(rotateXYZ(scale(center, s), rotationDeg), -1), 5) };
}

// The camera position that keeps the viewing direction, aims at `center` and fits a sphere of `radius`
// in a view of vertical field `fovDeg` and aspect `aspect` (width / height), with `margin` to spare.
export function framePosition(camera, center, radius, aspect, margin = 1.15) {
  const half = (camera.fov_deg || 35) * DEG / 2;
  const narrowest = Math.min(half, Math.atan(Math.tan(half) * Math.min(1, aspect || 1)));
  const direction = normalize(sub(camera.position, camera.target));
  const d = direction[0] || direction[1] || direction[2] ? direction : [0, 0, 1];
  return add(center, scale(d, (radius * margin) / Math.sin(narrowest)));
}

// The document's camera, with stand-ins for what it leaves out.
export function cameraOf(doc) {
  const c = doc.camera || {};
  return {
    position: c.position || [0, 0.5, 5], target: c.target || [0, -0.35, 0], up: c.up || [0, 1, 0], fov_deg: c.fov_deg || 35,
  };
}

// A camera as in the scene document: its unit axes and tan(vertical fov / 2).
function cameraBasis(camera) {
  const forward = normalize(sub(camera.target, camera.position));
  const right = normalize(cross(forward, camera.up || [0, 1, 0]));
  return { forward, right, up: cross(right, forward), t: Math.tan(((camera.fov_deg || 40) * DEG) / 2) };
}

// Projects a world point into normalised device coordinates for a camera as in the scene document.
// Returns null when the point is behind the camera.
export function project(camera, aspect, point) {
  const { forward, right, up, t } = cameraBasis(camera);
  const rel = sub(point, camera.position);
  const z = dot(rel, forward);
  if (z <= 1e-6) return null;
  return { x: dot(rel, right) / (z * t * aspect), y: dot(rel, up) / (z * t) };
}

// `point` moved across the view at its own depth by (dx, dy) in normalised device coordinates (2 across
// the image, y up), so that it stays under the pointer that drags it: project's inverse. A point behind
// the camera stays where it is.
export function panInView(camera, aspect, point, dx, dy) {
  const { forward, right, up, t } = cameraBasis(camera);
  const z = dot(sub(point, camera.position), forward);
  if (z <= 1e-6) return point;
  return add(point, add(scale(right, dx * z * t * aspect), scale(up, dy * z * t)));
}

// ---- colour --------------------------------------------------------------------------------------

const srgbToLinear = (c) => (c <= 0.04045 ? c / 12.92 : ((c + 0.055) / 1.055) ** 2.4);
const linearToSrgb = (c) => (c <= 0.0031308 ? c * 12.92 : 1.055 * c ** (1 / 2.4) - 0.055);

// "#rrggbb" (sRGB, as colour pickers speak) to linear RGB in [0, 1].
export function hexToLinear(hex) {
  const m = /^#?([0-9a-f]{2})([0-9a-f]{2})([0-9a-f]{2})$/i.exec(hex || '');
  if (!m) return [1, 1, 1];
  return [m[1], m[2], m[3]].map((h) => round(srgbToLinear(parseInt(h, 16) / 255), 4));
}

export function linearToHex(rgb) {
  const v = Array.isArray(rgb) && rgb.length === 3 ? rgb : [1, 1, 1];
  return '#' + v.map((c) => {
    const s = Math.round(linearToSrgb(Math.max(0, Math.min(1, Number(c) || 0))) * 255);
    return s.toString(16).padStart(2, '0');
  }).join('');
}

// ---- lights and objects ----------------------------------------------------------------------------
// A scene's lights and objects are collections keyed by name. The panel shows one of each, the
// selection, under the older form's singular names ('/light', '/object'), so its controls and the light
// marker need not know names; edits and error pointers are translated at the edges.

// Luminance of a linear RGB colour (Rec. 709).
export const luminance = (rgb) => 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];

// The irradiance (W/m^2, luminance) of the brightest pool the scene's lights throw on the floor (or, with
// no floor, on the level of the camera's target): a spot's on its axis, a point light's straight below it,
// a directional light's anywhere; 0 when no light reaches it. What an environment is balanced against.
export function lampIrradiance(doc) {
  const level = doc.floor?.enabled ? (doc.floor.height ?? -1) : (doc.camera?.target?.[1] ?? 0);
  let brightest = 0;
  for (const light of Object.values(doc.lights || {})) {
    const { type, power, axis, position } = lamp(light);
    const height = position[1] - level;
    let irradiance = 0;
    if (type === 'directional') irradiance = power * Math.max(0, -axis[1]);
    else if (height > 0 && type === 'point') irradiance = power / (height * height);
    else if (height > 0 && axis[1] < 0) {
      const distance = height / -axis[1];
      irradiance = (power * -axis[1]) / (distance * distance);
    }
    brightest = Math.max(brightest, irradiance);
  }
  return brightest;
}

// The keyed collections, by the name the panel gives the member it edits (`medium_volume`: the document's
// `volume` is the lattice's settings).
export const COLLECTIONS = { light: 'lights', object: 'objects', medium_volume: 'volumes' };
// What a member of each is called in words, and how few a scene may have.
export const MEMBER_NOUN = { light: 'light', object: 'object', medium_volume: 'volume' };
export const MIN_MEMBERS = { light: 1, object: 1, medium_volume: 0 };
// Fields every member of a collection must share (the daemon refuses objects of differing Abbe numbers:
// dispersion is one per scene): the panel's edit of one writes them all.
const SHARED = { object: ['abbe'] };

// Whether the daemon takes `name` as a member's name: 1 to 64 of [A-Za-z0-9_.-], not "." or "..".
export const validName = (name) => /^[A-Za-z0-9_.-]{1,64}$/.test(name) && name !== '.' && name !== '..';

export function memberNames(doc, kind) {
  return Object.keys((isObject(doc) && doc[COLLECTIONS[kind]]) || {}).sort();
}

// The selected member's name: `wanted` if the scene has it, else its first by name (null: none).
export function selectedName(doc, kind, wanted) {
  const names = memberNames(doc, kind);
  return names.includes(wanted) ? wanted : (names[0] ?? null);
}

// `doc` with `light` and `object` set to the selected members.
export function panelDocument(doc, selection) {
  const out = { ...doc };
  for (const [kind, plural] of Object.entries(COLLECTIONS)) {
    const name = selectedName(doc, kind, selection[kind]);
    out[kind] = name === null ? {} : doc[plural][name];
  }
  return out;
}

// A patch written against the panel document as a patch of the scene: '/light/...' edits the selected light
// (and a shared field, every member).
export function memberPatch(patch, doc, selection) {
  if (!isObject(patch)) return patch;
  let out = patch;
  for (const [kind, plural] of Object.entries(COLLECTIONS)) {
    if (!(kind in out)) continue;
    const name = selectedName(doc, kind, selection[kind]);
    const { [kind]: member, ...rest } = out;
    if (name === null) { out = rest; continue; }
    const shared = Object.fromEntries((SHARED[kind] || []).filter((k) => isObject(member) && k in member)
      .map((k) => [k, member[k]]));
    const others = Object.keys(shared).length ? memberNames(doc, kind).filter((n) => n !== name) : [];
    const members = Object.fromEntries(others.map((n) => [n, shared]));
    out = composePatches(rest, { [plural]: { ...members, [name]: member } });
  }
  return out;
}

// An error pointer into the selected member as the panel names it ('/lights/key/intensity' ->
// '/light/intensity'); any other pointer unchanged.
export function panelPointer(pointer, doc, selection) {
  const tokens = parsePointer(pointer);
  for (const [kind, plural] of Object.entries(COLLECTIONS)) {
    if (tokens[0] === plural && tokens.length >= 2 && tokens[1] === selectedName(doc, kind, selection[kind]))
      return ['', kind, ...tokens.slice(2)].map((t) => t.replace(/~/g, '~0').replace(/\//g, '~1')).join('/');
  }
  return pointer;
}

// A name for a new member: `base`, or else `base` followed by the first number not taken.
export function freeName(doc, kind, base) {
  const names = new Set(memberNames(doc, kind));
  if (!names.has(base)) return base;
  for (let i = 2; ; ++i) if (!names.has(`${base}${i}`)) return `${base}${i}`;
}

// What of a rejected `patch` to drop before re-sending the rest, for an error at `pointer`: that pointer,
// or, when the patch adds, removes or renames members of the collection it points into, the whole
// collection's part (a rename without its new name would remove the member). `doc`: the document the
// patch was written against.
export function rejectedScope(patch, pointer, doc) {
  const [top] = parsePointer(pointer);
  const plural = Object.values(COLLECTIONS).find((p) => p === top);
  const members = plural && isObject(patch) && isObject(patch[plural]) ? patch[plural] : null;
  if (!members) return pointer;
  const existing = (isObject(doc) && doc[plural]) || {};
  const structural = Object.entries(members).some(([name, value]) => value === null || !(name in existing));
  return structural ? `/${plural}` : pointer;
}
