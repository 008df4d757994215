// Files in and out: OBJ and HDR/EXR uploads, example scenes and imported documents (JSON or glTF) that
// replace the scene, the document exported as JSON, keyframes played into the view, and the frame saved as PNG.

import {
  OBJECT_SIZE, checkExample, environmentPatch, loadedExample, meshPatch, refreshEnvironments, refreshMeshes, refreshVolumes,
  rememberBounds, volumeSpot,
} from './catalog.js';
import { api } from './connection.js';
import { complain, controls } from './panel.js';
import * as S from './scene.js';
import { edit, play, replaceScene, stillAfterPreview } from './session.js';
import { hooks, panel, state, view } from './state.js';
import { announce, updateProgress } from './status.js';
import { newVolume } from './volumes.js';

// A name the daemon takes for an upload, made from its file's name.
function uploadName(fileName) {
  const base = fileName.replace(/\.[^.]*$/, '').toLowerCase().replace(/[^a-z0-9_-]+/g, '-').replace(/^-+|-+$/g, '');
  return (base || 'mesh').slice(0, 48);
}

// Uploads `file` with `put(name)`, which sends it and shows what came of it at `field` (a picker with a
// status line). A failure is said there instead; `pointer` is what the test hooks blame.
async function upload(file, field, pointer, put) {
  const name = uploadName(file.name);
  field.clearError();
  field.setStatus(`Uploading ${file.name}…`);
  try {
    await put(name);
  } catch (e) {
    field.setStatus('');
    const message = `${file.name}: ${e.message}`;
    complain(field, message, pointer, `Upload failed: ${message}`);
    return false;
  }
  return true;
}

// Uploads an .hdr or .exr file as an environment named after it, and lights the scene with it.
export function uploadEnvironment(file, field) {
  return upload(file, field, '/environment/image', async (name) => {
    const info = await api('PUT', `/api/environments/${encodeURIComponent(name)}`, await file.arrayBuffer(),
      'application/octet-stream');
    await refreshEnvironments();
    const { patch, note } = await environmentPatch(name);
    field.setStatus(`Uploaded “${name}” (${info?.width} x ${info?.height}). ${note}`.trim());
    edit(patch, true);
    controls.environment.update(view());
  });
}

// Uploads an OpenVDB file as a volume named after it. A scene without volumes gets one of it, placed as
// Add places one (beside the chosen object, sized by its box); otherwise Add places it.
export function uploadVolume(file, field) {
  return upload(file, field, '/volumes', async (name) => {
    const info = await api('PUT', `/api/volumes/${encodeURIComponent(name)}`, await file.arrayBuffer(),
      'application/octet-stream');
    await refreshVolumes();
    field.select.value = name;
    const grids = (info?.grids || []).filter((g) => g.usable).map((g) => g.name);
    const facts = `grids ${grids.join(', ')}`;
    if (S.memberNames(view(), 'medium_volume').length) {
      field.setStatus(`Uploaded “${name}” (${facts}); Add places it in the scene.`);
      return;
    }
    field.setStatus(`Uploaded “${name}” (${facts}) and placed it in the scene as “volume”.`);
    state.selected.medium_volume = 'volume';
    edit({ volumes: { volume: newVolume(name, grids, volumeSpot(name, panel())) } }, true);
  });
}

// Uploads an OBJ file as a mesh named after it and makes it the chosen object's, fitted unless the user
// keeps its own units (see catalog.js's meshPatch).
export async function uploadMesh(file, field) {
  const uploaded = await upload(file, field, '/object/mesh', async (name) => {
    const text = await file.text();
    const info = await api('PUT', `/api/meshes/${encodeURIComponent(name)}`, text, 'model/obj');
    const facts = [];
    if (typeof info?.triangles === 'number') facts.push(`${info.triangles} triangles`);
    if (typeof info?.vertices === 'number') facts.push(`${info.vertices} vertices`);
    if (info?.watertight === false) facts.push(`not watertight: ${info.boundary_edges ?? 'some'} open edges`);
    else if (info?.watertight === true) facts.push('watertight');
    if (info?.bounds) {
      rememberBounds(name, info.bounds);
      const size = Number(Math.max(...[0, 1, 2].map((i) => info.bounds.max[i] - info.bounds.min[i])).toPrecision(3));
      facts.push(`${size} unit${size === 1 ? '' : 's'} across`);
    }
    hooks.meshUploads++;
    hooks.lastUpload = { name, info };
    await refreshMeshes();
    const patch = meshPatch(`upload:${name}`);
    const fitted = patch.object.scale !== undefined;
    field.setStatus(`Uploaded “${name}”${facts.length ? ` (${facts.join(', ')})` : ''}` +
      (fitted ? `; scaled by ${patch.object.scale} to fit ${OBJECT_SIZE} m and centred.` : '; in its own units.'),
    patch.object.mesh);
    edit(patch, false);  // a preview of the new mesh, then its still
    stillAfterPreview();
    controls.mesh.update(panel());
  });
  if (!uploaded) field.el.scrollIntoView({ block: 'nearest' });
}

// A scene-level failure (a file that is not JSON, a document the daemon refuses) is shown at `field`.
function sceneError(field, what, e) {
  const where = e?.pointer ? ` (${e.pointer})` : '';
  complain(field, `${what}: ${e?.message || e}${where}`, e?.pointer ?? null);
}

export async function loadExample(name, field) {
  field.clearError();
  try {
    const got = await replaceScene(() => api('GET', `/api/examples/${encodeURIComponent(name)}`));
    loadedExample(name, got.scene);
    announce(`Loaded the example ${name}`);
  } catch (e) {
    sceneError(field, `Example “${name}”`, e);
  }
}

// The document a file holds: a scene document (JSON), or a glTF scene (.glb, or .gltf with its buffers
// inside), which the daemon maps as a scene of its own (uploading its meshes); that scene is only the way
// in and is deleted again, its meshes stay (the document names them). `warnings`: what the glTF says that
// has no meaning here.
async function documentOf(file) {
  if (!/\.(glb|gltf)$/i.test(file.name)) {
    let doc;
    try { doc = JSON.parse(await file.text()); } catch (e) { throw new Error(`not JSON (${e.message})`); }
    if (!S.isObject(doc)) throw new Error('not a scene document (a JSON object)');
    return { doc, warnings: [] };
  }
  const type = /\.glb$/i.test(file.name) ? 'model/gltf-binary' : 'model/gltf+json';
  const got = await api('POST', '/api/scenes', await file.arrayBuffer(), type);
  api('DELETE', `/api/scenes/${encodeURIComponent(got.id)}`).catch(() => {});
  return { doc: got.scene, warnings: got.warnings || [] };
}

export async function importScene(file, field) {
  field.clearError();
  field.status.textContent = `Reading ${file.name}…`;
  try {
    let warnings = [];
    await replaceScene(async () => {
      const read = await documentOf(file);
      warnings = read.warnings;
      return read.doc;
    });
    field.status.textContent = `Imported ${file.name}.` +
      (warnings.length ? ` Not taken (${warnings.length}): ${warnings.join('; ')}` : '');
    hooks.imports = (hooks.imports || 0) + 1;
    checkExample();
  } catch (e) {
    field.status.textContent = '';
    sceneError(field, file.name, e);
  }
}

// Plays a keyframe file (a list of {time, patch}, as `refract animate` takes) into this view; Stop, or
// any edit, ends it.
export async function playKeyframes(file, field) {
  field.clearError();
  let keyframes;
  try { keyframes = JSON.parse(await file.text()); } catch (e) {
    return sceneError(field, file.name, new Error(`not JSON (${e.message})`));
  }
  const started = await play(file.name, keyframes, {
    ended: (note) => {
      field.stopButton.hidden = true;
      field.status.textContent = note;
    },
    failed: (msg) => sceneError(field, file.name, { message: msg.error, pointer: msg.pointer }),
  });
  if (!started) return sceneError(field, file.name, new Error('not connected'));
  field.status.textContent = `Playing ${file.name}…`;
  field.stopButton.hidden = false;
  updateProgress();
}

function download(blob, fileName) {
  const url = URL.createObjectURL(blob);
  const a = document.createElement('a');
  a.href = url;
  a.download = fileName;
  document.body.append(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 1000);
  hooks.downloads++;
}

export function exportScene(field) {
  const doc = view();
  download(new Blob([JSON.stringify(doc, null, 2) + '\n'], { type: 'application/json' }), `refract-${state.sceneId}.json`);
  field.status.textContent = `Exported revision ${state.confirmedRevision} as refract-${state.sceneId}.json.`;
}

// Downloads the last frame exactly as the daemon sent it.
export function savePng() {
  if (!state.lastPng) return;
  const blob = state.lastPng.type ? state.lastPng : new Blob([state.lastPng], { type: 'image/png' });
  download(blob, `refract-${state.sceneId}-r${hooks.lastRevision ?? 0}.png`);
}
