// What the daemon offers besides the scene: meshes (built in and uploaded, with their bounds), environment
// images, volumes (built in and uploaded, with their grids) and example scenes; and which example the scene
// still is.

import { api } from './connection.js';
import { controls } from './panel.js';
import * as S from './scene.js';
import { hooks, panel, view } from './state.js';
import { frameAspect } from './viewport.js';

export const OBJECT_SIZE = 2;  // metres: the built-in meshes span [-1, 1]; uploads are fitted to this
// Bounds of the built-in meshes in their own units (server/mesh/mesh.cpp); uploads report theirs.
const BUILTIN_BOUNDS = {
  sphere: { min: [-1, -1, -1], max: [1, 1, 1] },
  cube: { min: [-1, -1, -1], max: [1, 1, 1] },
  torus: { min: [-1.35, -0.35, -1.35], max: [1.35, 0.35, 1.35] },
  prism: { min: [-0.866, -0.5, -1], max: [0.866, 1, 1] },
  bunny: { min: [-0.96883, -1, -0.56078], max: [0.96883, 1, 0.56078] },
};
const meshBounds = {};  // uploaded mesh name -> bounds in its own units
const volumeGrids = {};  // volume name (uploaded or built in) -> the names of its usable float grids
const volumeBoxes = {};  // volume name -> the box in its own world units around its usable grids' voxels
let example = null;     // { name, doc }: the example the scene still is

export function rememberBounds(name, bounds) {
  meshBounds[name] = bounds;
}

// Bounds of a mesh reference in its own units, when known.
function boundsOf(mesh) {
  if (typeof mesh !== 'string') return null;
  return mesh.startsWith('upload:') ? meshBounds[mesh.slice(7)] || null : BUILTIN_BOUNDS[mesh] || null;
}

// Where `object` lies in the world (S.placedBounds); a mesh of unknown bounds is taken for the sphere.
export function placedObject(object) {
  return S.placedBounds(boundsOf(object.mesh) || BUILTIN_BOUNDS.sphere, object);
}

// The scale and position of a new member of box `box` (its own units) beside the object the panel
// document `doc` shows, in the frames this viewer sees (S.besideObject); a new object is the sphere.
export const besideChosen = (doc, box = BUILTIN_BOUNDS.sphere) =>
  S.besideObject(placedObject(doc.object || {}), box, S.viewOf(doc, frameAspect()));

// Where a new volume of file `asset` goes in `doc`, built in or uploaded alike: beside the chosen object,
// sized by its box, where the lights reach it most; where its box is not known yet ({}), where its file
// puts it.
// Its density is scaled as its size is, inversely, so that it is as thick to light as its file made it.
export function volumeSpot(asset, doc) {
  if (!volumeBoxes[asset]) return {};
  const placed = placedObject(doc.object || {});
  // What the object shades: the ball of its box's least half-extent (the sphere itself, for the sphere).
  const blocker = { center: placed.center, radius: Math.min(...[0, 1, 2].map((i) => (placed.hi[i] - placed.lo[i]) / 2)) };
  const spot = S.besideObject(placed, volumeBoxes[asset], S.viewOf(doc, frameAspect()), (p) => S.lightAt(doc, p, blocker));
  return { ...spot, density_scale: Math.min(1000, Number((1 / spot.scale).toPrecision(3))) };
}

// The edit that gives volume `member` file `asset` in place of its own: standing where it stood, as large.
export const volumeSwapSpot = (member, asset) => (volumeBoxes[member.asset] && volumeBoxes[asset]
  ? S.standInstead(volumeBoxes[member.asset], volumeBoxes[asset], member) : {});

// A volume's box in its own world units: its usable grids' world boxes (the corners of their active
// voxels' centres, GET /api/volumes) grown by a voxel, which trilinear lookups reach past those centres.
// The daemon adds no offset: a member's scale, rotation and position apply to these coordinates.
function volumeBox(grids) {
  const boxes = grids.filter((g) => g.usable && g.world_bounds).map((g) => {
    const pad = Math.max(...(g.voxel_size || [0]));
    return { min: g.world_bounds.min.map((v) => v - pad), max: g.world_bounds.max.map((v) => v + pad) };
  });
  if (!boxes.length) return null;
  return {
    min: [0, 1, 2].map((i) => Math.min(...boxes.map((b) => b.min[i]))),
    max: [0, 1, 2].map((i) => Math.max(...boxes.map((b) => b.max[i]))),
  };
}

// The edit that picks `mesh`: unless the user keeps its own units, it is fitted to the default object
// size with its centre where the object's origin is (object.position [0, 0, 0]).
export function meshPatch(mesh) {
  const bounds = boundsOf(mesh);
  if (controls.mesh.keepUnits.checked || !bounds) return { object: { mesh } };
  const { scale, position } = S.fitObject(bounds, OBJECT_SIZE, panel().object?.rotation_deg);
  return { object: { mesh, scale, position } };
}

export async function refreshMeshes() {
  try {
    const list = await api('GET', '/api/meshes');
    const items = Array.isArray(list) ? list : (list?.meshes || []);
    const names = items.map((m) => (typeof m === 'string' ? m : m?.name)).filter(Boolean).sort();
    for (const m of items) if (m?.name && m.bounds) meshBounds[m.name] = m.bounds;
    controls.mesh.setMeshes(names);
    controls.mesh.update(panel());
  } catch { /* the built-in meshes still work */ }
}

// The usable grids of volume `name`, as listed when last asked.
export const volumeGridsOf = (name) => volumeGrids[name] || [];
// The volume the panel shows: Add places it.
export const chosenVolumeAsset = () => controls.volumes.select.value || null;

export async function refreshVolumes() {
  try {
    const list = await api('GET', '/api/volumes');
    const names = (items) => (items || []).map((v) => v?.name).filter(Boolean);
    for (const v of [...(list?.volumes || []), ...(list?.builtin || [])]) {
      volumeGrids[v.name] = (v.grids || []).filter((g) => g.usable).map((g) => g.name);
      volumeBoxes[v.name] = volumeBox(v.grids || []);
    }
    controls.volumes.setVolumes(names(list?.volumes).sort(), names(list?.builtin));
    controls.update(panel());
  } catch { /* volumes already in the scene still render */ }
}

// Everything the daemon offers besides the scene, asked for at once.
export function refreshCatalog() {
  refreshMeshes();
  refreshEnvironments();
  refreshExamples();
  refreshVolumes();
}

export async function refreshEnvironments() {
  try {
    const list = await api('GET', '/api/environments');
    controls.environment.setImages((list?.environments || []).map((e) => e?.name).filter(Boolean));
    controls.environment.update(view());
  } catch { /* the sky and a uniform colour still work */ }
}

// An environment image lights a scene that has lamps of its own at the intensity that puts half the
// brightest lamp's irradiance on the floor: its pool stays three times as bright as the rest, where the
// image at intensity 1 (a sunny sky gives ten times a 26 W/sr lamp's floor) would wash the lamps out.
export const ENVIRONMENT_SHARE_OF_LAMPS = 0.5;

// The edit that lights the scene with the environment image `name`, and what it says about its intensity.
export async function environmentPatch(name) {
  const environment = { type: 'image', image: name };
  const doc = view();
  const lamps = S.lampIrradiance(doc);
  if (!(lamps > 0) || doc.environment?.lights === false) return { patch: { environment }, note: '' };
  const info = await api('GET', `/api/environments/${encodeURIComponent(name)}`);
  const own = S.luminance(info?.irradiance ?? [0, 0, 0]);
  if (!(own > 0)) return { patch: { environment }, note: '' };
  environment.intensity = Number(((ENVIRONMENT_SHARE_OF_LAMPS * lamps) / own).toPrecision(2));
  const brighter = Number((own / lamps).toPrecision(2));
  return {
    patch: { environment },
    note: `Intensity ${environment.intensity}: “${name}” lights the floor half as much as the brightest lamp ` +
      `(at 1 it is ${brighter}× as bright). Raise it for daylight.`,
  };
}

export async function refreshExamples() {
  try {
    const list = await api('GET', '/api/examples');
    controls.example.setExamples(Array.isArray(list?.examples) ? list.examples : []);
    checkExample();
  } catch { /* an older daemon: no examples */ }
}

// The example's name stays shown while the scene is that example (the image size aside).
const withoutImageSize = (doc) => S.applyMergePatch(doc, { image: { width: null, height: null } });

export function checkExample() {
  if (example && !S.deepEqual(withoutImageSize(view()), example.doc)) example = null;
  hooks.example = example?.name ?? null;
  controls.example.showLoaded(hooks.example);
}

// The scene was just made the example `name`, whose document the daemon answered with.
export function loadedExample(name, scene) {
  example = { name, doc: withoutImageSize(scene) };
  checkExample();
}
