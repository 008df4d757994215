// The panel's fields that pick or act rather than hold one value: example scenes, files (scene documents,
// keyframes), meshes, environments, and the outliners of lights, objects and volumes. What they do is in the
// `actions` the panel is built with (see main.js).

import { h } from './dom.js';
import { Field, isEditing } from './fields.js';
import { COLLECTIONS, MEMBER_NOUN, MIN_MEMBERS, deepEqual, getAt } from './scene.js';

const BUILTIN_MESHES = [['sphere', 'Sphere'], ['cube', 'Cube'], ['torus', 'Torus'], ['prism', 'Prism'], ['bunny', 'Bunny']];

// Example scenes, listed by the daemon (GET /api/examples); "Load" replaces the scene with one.
export class ExampleField extends Field {
  constructor(spec, emit, actions) {
    const id = 'ctl-example';
    super(spec, [], 'Example scene', id);
    this.select = h('select', { id }, h('option', { value: '', text: 'Choose an example…' }));
    this.button = h('button', { type: 'button', id: 'example-load', text: 'Load' });
    this.note = h('p', { class: 'note', id: `${id}-note`, 'aria-live': 'polite' });
    const load = () => { if (this.select.value) actions.loadExample(this.select.value, this); };
    this.button.addEventListener('click', load);
    this.select.addEventListener('keydown', (e) => { if (e.key === 'Enter') { e.preventDefault(); load(); } });
    this.describe(this.select);
    this.el.append(this.label, h('div', { class: 'row' }, this.select, this.button), this.note, this.error);
  }
  setExamples(list) {
    const current = this.select.value;
    this.select.replaceChildren(h('option', { value: '', text: 'Choose an example…' }),
      ...list.map((e) => h('option', { value: e.name, text: e.title || e.name })));
    this.select.value = current;
  }
  // Shows which example the scene is (null: none, or edited away from it).
  showLoaded(name) {
    if (!isEditing(this.select)) this.select.value = name || '';
  }
}

// A hidden file input with a button-like label; `onFile(file)` gets the file picked.
export function filePicker(id, accept, text, onFile) {
  const input = h('input', { type: 'file', id, accept, class: 'file-input' });
  input.addEventListener('change', () => {
    const f = input.files && input.files[0];
    if (f) onFile(f);
    input.value = '';
  });
  return { input, label: h('label', { for: id, class: 'button-like', text }) };
}

// Importing the scene document from a JSON or glTF file, and exporting it as JSON.
export class SceneFileField extends Field {
  constructor(spec, emit, actions) {
    const id = 'scene-file';
    super(spec, [], 'Scene document', id);
    const picker = filePicker(id, '.json,application/json,.glb,.gltf,model/gltf-binary,model/gltf+json', 'Import JSON or glTF…',
      (f) => actions.importScene(f, this));
    this.file = picker.input;
    this.exportButton = h('button', { type: 'button', id: 'scene-export', text: 'Export JSON' });
    this.status = h('p', { class: 'note', id: 'scene-file-status', 'aria-live': 'polite' });
    this.exportButton.addEventListener('click', () => actions.exportScene(this));
    // An animation (keyframes: a list of {time, patch}, as `refract animate` takes) played into this view.
    const play = filePicker('keyframes-file', '.json,application/json', 'Play keyframes…', (f) => actions.playKeyframes(f, this));
    this.playFile = play.input;
    this.stopButton = h('button', { type: 'button', id: 'play-stop', text: 'Stop', hidden: true });
    this.stopButton.addEventListener('click', () => actions.stopPlay());
    this.describe(this.file);
    // A scene file dropped anywhere on the page is imported as if chosen here; any other dropped file is
    // kept from replacing the page (the browser's default), and said so.
    window.addEventListener('dragover', (e) => {
      if (e.dataTransfer?.types?.includes('Files')) e.preventDefault();
    });
    window.addEventListener('drop', (e) => {
      const f = e.dataTransfer?.files?.[0];
      if (!f) return;
      e.preventDefault();
      if (/\.(json|glb|gltf)$/i.test(f.name)) actions.importScene(f, this);
      else this.status.textContent = `${f.name}: drop a scene (.json, .glb or .gltf) here; meshes go through Upload OBJ…`;
    });
    this.el.append(this.label, h('div', { class: 'row' }, this.file, picker.label, this.exportButton),
      h('div', { class: 'row' }, this.playFile, play.label, this.stopButton), this.status, this.error);
  }
}

// Lists `names` (values `prefix` + name) in `select`'s option group `group`, hidden while empty; the
// choice made stays.
function fillGroup(select, group, prefix, names) {
  const current = select.value;
  group.replaceChildren(...names.map((n) => h('option', { value: `${prefix}${n}`, text: n })));
  group.hidden = names.length === 0;
  if (current) select.value = current;
}

// Mesh picker: built-in shapes and uploaded OBJ meshes, plus an upload button.
export class MeshField extends Field {
  constructor(spec, emit, actions) {
    const id = 'ctl-object-mesh';
    super(spec, ['/object/mesh'], 'Mesh', id);
    this.select = h('select', { id });
    this.builtin = h('optgroup', { label: 'Built-in' }, BUILTIN_MESHES.map(([v, t]) => h('option', { value: v, text: t })));
    this.uploaded = h('optgroup', { label: 'Uploaded', hidden: true });
    this.select.append(this.builtin, this.uploaded);
    this.select.addEventListener('change', () => emit(this, actions.meshPatch(this.select.value), true));
    const picker = filePicker('mesh-file', '.obj,model/obj,text/plain', 'Upload OBJ…', (f) => actions.uploadMesh(f, this));
    this.file = picker.input;
    this.keepUnits = h('input', { type: 'checkbox', id: 'mesh-keep-units' });
    const keepLabel = h('label', { for: 'mesh-keep-units', class: 'check small' }, this.keepUnits,
      h('span', { text: 'Keep the mesh’s own units (otherwise it is fitted to 2 m and centred)' }));
    this.status = h('p', { class: 'note', id: 'mesh-status', 'aria-live': 'polite' });
    this.describe(this.select, this.file);
    this.el.append(this.label, h('div', { class: 'row' }, this.select, this.file, picker.label), keepLabel, this.status,
      this.error);
  }
  setMeshes(names) { fillGroup(this.select, this.uploaded, 'upload:', names); }
  // Upload news stays only while the scene uses that mesh.
  setStatus(text, mesh = null) {
    this.status.textContent = text;
    this.statusMesh = mesh;
  }
  update(doc) {
    const v = getAt(doc, '/object/mesh');
    if (typeof v !== 'string' || isEditing(this.select)) return;
    if (this.statusMesh && this.statusMesh !== v) this.setStatus('');
    if (v.startsWith('upload:') && ![...this.uploaded.children].some((o) => o.value === v)) {
      this.uploaded.append(h('option', { value: v, text: v.slice(7) }));
      this.uploaded.hidden = false;
    }
    this.select.value = v;
  }
}

// The outliner of one collection (lights, objects, volumes): which member the panel edits; members can be
// added, removed (down to the collection's least) and renamed.
export class MembersField extends Field {
  constructor(spec, emit, actions) {
    const kind = spec.member;
    const id = `ctl-${kind}-member`;
    super(spec, [`/${COLLECTIONS[kind]}`], spec.label, id);
    const noun = MEMBER_NOUN[kind];
    const members = actions.members;
    this.kind = kind;
    this.members = members;
    this.select = h('select', { id, size: 2, class: 'member-list' });  // a list box: every member in view
    this.select.addEventListener('change', () => members.select(kind, this.select.value));
    this.addButton = h('button', { type: 'button', id: `${kind}-add`, text: 'Add' });
    this.removeButton = h('button', { type: 'button', id: `${kind}-remove`, text: 'Remove' });
    this.addButton.addEventListener('click', () => members.add(kind));
    this.removeButton.addEventListener('click', () => members.remove(kind));
    this.name = h('input', { type: 'text', id: `${kind}-name`, 'aria-label': `New name for the chosen ${noun}`, maxlength: 64,
      title: `New name for the chosen ${noun}`, placeholder: 'New name' });
    this.renameButton = h('button', { type: 'button', id: `${kind}-rename`, text: 'Rename' });
    const rename = () => { this.clearError(); members.rename(kind, this.name.value.trim(), this); };
    this.renameButton.addEventListener('click', rename);
    this.name.addEventListener('keydown', (e) => { if (e.key === 'Enter') { e.preventDefault(); rename(); } });
    this.describe(this.select, this.name);
    this.alwaysShows = true;  // its error is about an action, not a value: the list follows the document
    this.el.append(this.label, h('div', { class: 'row members' }, this.select,
      h('div', { class: 'member-actions' }, this.addButton, this.removeButton)),
    h('div', { class: 'row' }, this.name, this.renameButton), this.error);
  }
  update(doc) {
    const names = Object.keys(doc[COLLECTIONS[this.kind]] || {}).sort();
    const chosen = this.members.selected(this.kind);
    if (names.join('/') !== [...this.select.options].map((o) => o.value).join('/')) {
      this.select.replaceChildren(...names.map((n) => h('option', { value: n, text: n })));
      this.select.size = Math.max(2, Math.min(names.length, 6));
    }
    if (!isEditing(this.select)) this.select.value = chosen ?? '';
    if (!isEditing(this.name)) this.name.value = chosen ?? '';
    this.removeButton.disabled = names.length <= MIN_MEMBERS[this.kind];
    this.renameButton.disabled = names.length === 0;
  }
}

// Environment picker: the dark sky, a uniform colour or an image (built in or uploaded), plus an upload
// button for .hdr and .exr files.
export class EnvironmentField extends Field {
  constructor(spec, emit, actions) {
    const id = 'ctl-environment';
    super(spec, ['/environment/type', '/environment/image'],
      'Environment (seen past the scene and in reflections; a colour or an image lights the scene too)', id);
    this.select = h('select', { id }, [['sky', 'Dark sky'], ['uniform', 'Uniform colour']]
      .map(([v, t]) => h('option', { value: v, text: t })));
    this.images = h('optgroup', { label: 'Images', hidden: true });
    this.select.append(this.images);
    this.select.addEventListener('change', async () => {
      const v = this.select.value;
      this.setStatus('');
      if (!v.startsWith('image:')) return emit(this, { environment: { type: v } }, true);
      try {
        const { patch, note } = await actions.environmentPatch(v.slice(6));
        this.setStatus(note);
        emit(this, patch, true);
      } catch (e) {
        this.select.value = this.shown;  // the scene's environment is unchanged
        this.setError(`Could not read the environment “${v.slice(6)}”: ${e.message}`);
      }
    });
    const picker = filePicker('environment-file', '.hdr,.exr', 'Upload HDR/EXR…', (f) => actions.uploadEnvironment(f, this));
    this.status = h('p', { class: 'note', id: 'environment-status', 'aria-live': 'polite' });
    this.describe(this.select, picker.input);
    this.el.append(this.label, h('div', { class: 'row' }, this.select, picker.input, picker.label), this.status,
      this.error);
  }
  setImages(names) { fillGroup(this.select, this.images, 'image:', names); }
  setStatus(text) { this.status.textContent = text; }
  update(doc) {
    if (isEditing(this.select)) return;
    const env = doc.environment || {};
    const v = env.type === 'image' ? `image:${env.image}` : (env.type || 'sky');
    if (env.type === 'image' && ![...this.images.children].some((o) => o.value === v)) {
      this.images.append(h('option', { value: v, text: env.image }));
      this.images.hidden = false;
    }
    this.select.value = v;
    this.shown = v;
  }
}

// This viewer's view: its own camera (orbiting moves it alone; saved to the scene on request) or the
// scene's camera, followed (presenter mode: this viewer's orbit moves it for every follower).
export class ViewField extends Field {
  constructor(spec, emit, actions) {
    const id = 'view-follow';
    super(spec, [], 'Your view', id);
    this.alwaysShows = true;
    this.follow = h('button', { type: 'button', id, class: 'toggle', 'aria-pressed': 'false', text: 'Follow the scene’s camera',
      title: 'Look through the scene’s own camera; your orbit then moves it for everyone who follows it (presenter mode)' });
    this.save = h('button', { type: 'button', id: 'view-save', text: 'Save this view to the scene',
      title: 'Make your camera the scene’s camera: what new viewers, exports and `refract render` start from' });
    this.note = h('p', { class: 'note', id: 'view-note', 'aria-live': 'polite' });
    this.following = actions.following;
    this.sceneCamera = actions.sceneCamera;
    this.follow.addEventListener('click', () => actions.setFollow(!this.following()));
    this.save.addEventListener('click', () => actions.saveView());
    this.describe(this.follow, this.save);
    this.el.append(this.label, h('div', { class: 'row wrap' }, this.follow, this.save), this.note, this.error);
  }
  // `doc` as this viewer sees it (its own camera, or the scene's when following).
  update(doc) {
    const on = this.following();
    const saved = !on && deepEqual(doc.camera, this.sceneCamera());
    this.follow.setAttribute('aria-pressed', String(on));
    this.save.disabled = on || saved;
    if (on) this.note.textContent = 'You look through the scene’s camera: your orbit moves it for everyone who follows it.';
    else if (saved) this.note.textContent = 'Your view is the scene’s saved view. Orbiting moves only yours.';
    else this.note.textContent = 'Your own camera: orbiting moves only your view. The scene keeps its own until you save yours.';
  }
}
