// The control panel: built from one declarative table. Every control knows the JSON pointers it
// writes, so a validation error from the daemon (which names a pointer) lands next to its control.

import { getAt, hexToLinear, linearToHex, parsePointer, patchAt, round } from './scene.js';

// Sliders whose position is not the value itself: `fromSlider` maps a slider position to the value,
// `toSlider` back, `numberStep` is the exact-value box's step.
const LOG2_SLIDER = { fromSlider: (r) => 2 ** r, toSlider: (v) => Math.log2(Math.max(1, v)), numberStep: 1 };
// Dispersion grows as 1 / Abbe number, so the slider moves along 1/V: 0 is none, the far end V = 5.
// The box holds the Abbe number itself.
const INVERSE_SLIDER = {
  fromSlider: (r) => (r > 0 ? Math.round(10 / r) / 10 : 0), toSlider: (v) => (v > 0 ? 1 / v : 0), numberStep: 1,
};
// Scale spans five decades (an OBJ in millimetres wants 0.001, a small one 100): the slider moves along
// log10; the box shows three significant digits.
const LOG10_SLIDER = {
  fromSlider: (r) => Number((10 ** r).toPrecision(3)), toSlider: (v) => Math.log10(Math.max(1e-3, v)),
  numberStep: 'any', format: (v) => String(Number(v.toPrecision(4))),
};

export const SECTIONS = [
  {
    id: 'scene', title: 'Scene', controls: [
      { kind: 'example' },
      { kind: 'mesh' },
      { kind: 'file' },
    ],
  },
  {
    id: 'light', title: 'Light', controls: [
      { kind: 'members', member: 'light', label: 'Lights (the panel edits the one chosen)' },
      { kind: 'select', ptr: '/light/type', label: 'Light type',
        options: [['point', 'Point'], ['spot', 'Spot'], ['directional', 'Directional']] },
      { kind: 'range', ptr: '/light/intensity', label: 'Intensity', min: 0, max: 200, step: 0.5 },
      { kind: 'color', ptr: '/light/color', label: 'Colour' },
      { kind: 'range', ptr: '/light/cone_deg', label: 'Spot cone (half-angle, °)', min: 1, max: 90, step: 1,
        showIf: (doc) => doc.light?.type === undefined || doc.light.type === 'spot' },
    ],
  },
  {
    id: 'object', title: 'Object', controls: [
      { kind: 'members', member: 'object', label: 'Objects (the panel and Alt+drag edit the one chosen)' },
      { kind: 'select', ptr: '/object/index_field', label: 'Index field',
        options: [['uniform', 'Uniform'], ['luneburg', 'Luneburg lens'], ['maxwell', 'Maxwell fish-eye']] },
      { kind: 'range', ptr: '/object/ior', label: 'Index of refraction', min: 1, max: 4, step: 0.01,
        showIf: (doc) => (doc.object?.index_field ?? 'uniform') === 'uniform' },
      { kind: 'range', ptr: '/object/maxwell_n0', label: 'Fish-eye central index n₀', min: 1, max: 4, step: 0.01,
        showIf: (doc) => doc.object?.index_field === 'maxwell' },
      { kind: 'range', ptr: '/object/abbe', label: 'Dispersion: Abbe number (0 = none; glass 30-60; one for all objects)',
        min: 0, max: 0.2, step: 0.002, ...INVERSE_SLIDER },
      { kind: 'checkbox', ptr: '/object/fresnel', label: 'Fresnel reflection at the surface',
        showIf: (doc) => ['uniform', 'maxwell'].includes(doc.object?.index_field ?? 'uniform') },
      { kind: 'range', ptr: '/object/film/top_nm', label: 'Thin film: thickness at the top (nm; 0 = none)',
        min: 0, max: 2000, step: 5, showIf: (doc) => doc.object?.fresnel !== false },
      { kind: 'range', ptr: '/object/film/bottom_nm', label: 'Thin film: thickness at the bottom (nm)',
        min: 0, max: 2000, step: 5, showIf: (doc) => doc.object?.fresnel !== false },
      { kind: 'range', ptr: '/object/film/ior', label: 'Thin film: index (soap 1.33, MgF₂ 1.38)',
        min: 1, max: 2.5, step: 0.01, showIf: (doc) => doc.object?.fresnel !== false },
      { kind: 'range', ptr: '/object/scale', label: 'Scale', min: -3, max: 2, step: 0.01, ...LOG10_SLIDER },
      { kind: 'range', ptr: '/object/resolution', label: 'Own resolution (voxels across it; 0 = the scene’s voxel)',
        min: 0, max: 256, step: 16 },
      { kind: 'vec3', ptr: '/object/position', label: 'Position (m)', step: 0.05 },
      { kind: 'vec3', ptr: '/object/rotation_deg', label: 'Rotation (°, about x, then y, then z)', step: 5 },
      { kind: 'rgb', ptr: '/object/extinction', label: 'Extinction (per m)', min: 0, max: 10, step: 0.01 },
      { kind: 'rgb', ptr: '/object/scattering', label: 'Scattering (per m)', min: 0, max: 10, step: 0.01 },
      { kind: 'select', ptr: '/object/phase/model', label: 'Phase function',
        options: [['isotropic', 'Isotropic'], ['henyey-greenstein', 'Henyey-Greenstein'], ['schlick', 'Schlick']] },
      { kind: 'range', ptr: '/object/phase/g', label: 'Phase anisotropy g', min: -0.95, max: 0.95, step: 0.01,
        showIf: (doc) => doc.object?.phase?.model !== 'isotropic' },
    ],
  },
  {
    id: 'medium', title: 'Fog', controls: [
      { kind: 'fog', label: 'Fog density (per m)', min: 0, max: 1.5, step: 0.01 },
      { kind: 'range', ptr: '/medium/phase/g', label: 'Fog anisotropy g', min: -0.95, max: 0.95, step: 0.01 },
      { kind: 'range', ptr: '/photons/max_bounces', label: 'Scattering bounces (0 = single scattering; previews take at most 4)',
        min: 0, max: 64, step: 1 },
      { kind: 'checkbox', ptr: '/floor/enabled', label: 'Floor' },
      { kind: 'checkbox', ptr: '/floor/checker', label: 'Checkered floor' },
    ],
  },
  {
    id: 'environment', title: 'Environment', controls: [
      { kind: 'environment' },
      { kind: 'color', ptr: '/environment/color', label: 'Environment colour',
        showIf: (doc) => doc.environment?.type === 'uniform' },
      { kind: 'range', ptr: '/environment/intensity', label: 'Environment intensity', min: 0, max: 20, step: 0.05 },
      { kind: 'range', ptr: '/environment/rotation_deg', label: 'Environment rotation (° about the vertical)',
        min: -180, max: 180, step: 1, showIf: (doc) => doc.environment?.type === 'image' },
      { kind: 'checkbox', ptr: '/environment/lights', label: 'The environment lights the scene (off: a backdrop only)',
        showIf: (doc) => ['uniform', 'image'].includes(doc.environment?.type) },
    ],
  },
  {
    id: 'camera', title: 'Camera', controls: [
      { kind: 'range', ptr: '/camera/fov_deg', label: 'Field of view (vertical, °)', min: 10, max: 120, step: 1 },
    ],
  },
  {
    id: 'quality', title: 'Quality', controls: [
      { kind: 'range', ptr: '/photons/count', label: 'Photons', min: 10, max: 22, step: 1, ...LOG2_SLIDER },
      { kind: 'range', ptr: '/volume/resolution', label: 'Volume resolution (voxels)', min: 32, max: 512, step: 16 },
      { kind: 'range', ptr: '/image/exposure', label: 'Exposure (stops)', min: -4, max: 4, step: 0.1 },
    ],
  },
];

const BUILTIN_MESHES = [['sphere', 'Sphere'], ['cube', 'Cube'], ['torus', 'Torus'], ['prism', 'Prism'], ['bunny', 'Bunny']];

function h(tag, attrs = {}, ...children) {
  const el = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (v === undefined || v === null || v === false) continue;
    if (k === 'class') el.className = v;
    else if (k === 'text') el.textContent = v;
    else if (k === 'dataset') Object.assign(el.dataset, v);
    else el.setAttribute(k, v === true ? '' : String(v));
  }
  for (const c of children.flat()) if (c !== null && c !== undefined) el.append(c);
  return el;
}

const idFor = (ptr) => 'ctl' + ptr.replace(/[^a-z0-9]+/gi, '-');
const num = (value) => (value === '' || value === null || value === undefined ? NaN : Number(value));
const isEditing = (el) => el && document.activeElement === el;

function fmt(value, step, format) {
  if (typeof value !== 'number' || !Number.isFinite(value)) return '';
  if (format) return format(value);
  const digits = step >= 1 ? 0 : Math.min(4, Math.max(1, Math.ceil(-Math.log10(step))));
  return String(round(value, digits));
}

// Base: a labelled field with an inline error slot.
class Field {
  constructor(spec, ptrs, labelText, labelFor) {
    this.spec = spec;
    this.ptrs = ptrs;
    this.errorId = `${labelFor || idFor(ptrs[0] || spec.kind)}-error`;
    this.error = h('p', { class: 'field-error', id: this.errorId, hidden: true });
    this.label = h('label', { for: labelFor, id: `${labelFor}-label`, text: labelText });
    this.el = h('div', { class: `field field-${spec.kind}`, dataset: { pointers: ptrs.join(' ') } });
    this.inputs = [];  // elements that get aria-invalid / aria-describedby
    this.invalid = false;
  }
  describe(...inputs) {
    for (const input of inputs) {
      this.inputs.push(input);
      const ids = new Set((input.getAttribute('aria-describedby') || '').split(' ').filter(Boolean));
      ids.add(this.errorId);
      input.setAttribute('aria-describedby', [...ids].join(' '));
    }
  }
  setError(message) {
    this.invalid = true;
    this.el.classList.add('invalid');
    this.error.textContent = message;
    this.error.hidden = false;
    for (const input of this.inputs) input.setAttribute('aria-invalid', 'true');
  }
  clearError() {
    if (!this.invalid) return;
    this.invalid = false;
    this.el.classList.remove('invalid');
    this.error.textContent = '';
    this.error.hidden = true;
    for (const input of this.inputs) input.removeAttribute('aria-invalid');
  }
  focus() { this.inputs[0]?.focus(); }
  update() {}
}

class RangeField extends Field {
  constructor(spec, emit) {
    const id = idFor(spec.ptr);
    super(spec, [spec.ptr], spec.label, id);
    this.range = h('input', { type: 'range', id, min: spec.min, max: spec.max, step: spec.step });
    this.number = h('input', {
      type: 'number', id: `${id}-num`, class: 'num', step: this.numberStep(), inputmode: 'decimal',
      'aria-label': `${spec.label}, exact value`,
    });
    const fromRange = () => (spec.fromSlider ? spec.fromSlider(num(this.range.value)) : num(this.range.value));
    this.range.addEventListener('input', () => {
      this.number.value = fmt(fromRange(), this.numberStep(), spec.format);
      emit(this, patchAt(spec.ptr, fromRange()), false);
    });
    this.range.addEventListener('change', () => emit(this, patchAt(spec.ptr, fromRange()), true));
    this.number.addEventListener('change', () => {
      const v = num(this.number.value);
      if (!Number.isFinite(v)) { this.setError('Enter a number.'); return; }
      this.setRange(v);
      emit(this, patchAt(spec.ptr, v), true);
    });
    this.describe(this.number, this.range);
    this.el.append(this.label, h('div', { class: 'row' }, this.range, this.number), this.error);
  }
  numberStep() { return this.spec.numberStep ?? this.spec.step; }
  setRange(v) { this.range.value = String(this.spec.toSlider ? this.spec.toSlider(v) : v); }
  update(doc) {
    const v = getAt(doc, this.spec.ptr);
    if (typeof v !== 'number') return;
    if (!isEditing(this.range)) this.setRange(v);
    if (!isEditing(this.number)) this.number.value = fmt(v, this.numberStep(), this.spec.format);
  }
}

class SelectField extends Field {
  constructor(spec, emit) {
    const id = idFor(spec.ptr);
    super(spec, [spec.ptr], spec.label, id);
    this.select = h('select', { id }, spec.options.map(([v, t]) => h('option', { value: v, text: t })));
    this.select.addEventListener('change', () => emit(this, patchAt(spec.ptr, this.select.value), true));
    this.describe(this.select);
    this.el.append(this.label, this.select, this.error);
  }
  update(doc) {
    const v = getAt(doc, this.spec.ptr);
    if (typeof v === 'string' && !isEditing(this.select)) this.select.value = v;
  }
}

class CheckboxField extends Field {
  constructor(spec, emit) {
    const id = idFor(spec.ptr);
    super(spec, [spec.ptr], '', id);
    this.box = h('input', { type: 'checkbox', id });
    this.box.addEventListener('change', () => emit(this, patchAt(spec.ptr, this.box.checked), true));
    this.describe(this.box);
    this.label = h('label', { for: id, class: 'check' }, this.box, h('span', { text: spec.label }));
    this.el.append(this.label, this.error);
  }
  update(doc) {
    const v = getAt(doc, this.spec.ptr);
    if (typeof v === 'boolean') this.box.checked = v;
  }
}

class ColorField extends Field {
  constructor(spec, emit) {
    const id = idFor(spec.ptr);
    super(spec, [spec.ptr], spec.label, id);
    this.picker = h('input', { type: 'color', id, value: '#ffffff' });
    this.picker.addEventListener('input', () => emit(this, patchAt(spec.ptr, hexToLinear(this.picker.value)), false));
    this.picker.addEventListener('change', () => emit(this, patchAt(spec.ptr, hexToLinear(this.picker.value)), true));
    this.describe(this.picker);
    this.el.append(h('div', { class: 'row' }, this.label, this.picker), this.error);
  }
  update(doc) {
    const v = getAt(doc, this.spec.ptr);
    if (Array.isArray(v) && !isEditing(this.picker)) this.picker.value = linearToHex(v);
  }
}

// An RGB coefficient: one slider that sets all channels, plus an exact number per channel.
class RgbField extends Field {
  constructor(spec, emit) {
    const id = idFor(spec.ptr);
    super(spec, [spec.ptr], spec.label, id);
    this.all = h('input', { type: 'range', id, min: spec.min, max: spec.max, step: spec.step,
      'aria-valuetext': '' });
    this.channels = ['red', 'green', 'blue'].map((name, i) => h('input', {
      type: 'number', id: `${id}-${'rgb'[i]}`, class: `num ch ch-${'rgb'[i]}`, step: spec.step, min: spec.min,
      inputmode: 'decimal', 'aria-label': `${spec.label}, ${name} channel`, title: `${name} channel`,
    }));
    const readChannels = () => this.channels.map((c) => num(c.value));
    this.all.addEventListener('input', () => {
      const v = num(this.all.value);
      for (const c of this.channels) c.value = fmt(v, spec.step);
      emit(this, patchAt(spec.ptr, [v, v, v]), false);
    });
    this.all.addEventListener('change', () => emit(this, patchAt(spec.ptr, readChannels()), true));
    for (const c of this.channels) {
      c.addEventListener('change', () => {
        const v = readChannels();
        if (!v.every(Number.isFinite)) { this.setError('Enter a number for each channel.'); return; }
        this.all.value = String(Math.max(...v));
        emit(this, patchAt(spec.ptr, v), true);
      });
    }
    this.describe(this.all, ...this.channels);
    this.el.append(this.label, h('div', { class: 'row' }, this.all),
      h('div', { class: 'row channels', role: 'group', 'aria-label': `${spec.label} per channel` }, this.channels),
      this.error);
  }
  update(doc) {
    const v = getAt(doc, this.spec.ptr);
    if (!Array.isArray(v) || v.length !== 3) return;
    this.channels.forEach((c, i) => { if (!isEditing(c)) c.value = fmt(v[i], this.spec.step); });
    if (!isEditing(this.all)) this.all.value = String(Math.max(...v));
    this.all.setAttribute('aria-valuetext', v.map((x) => fmt(x, this.spec.step)).join(', '));
  }
}

// A vec3 (position, rotation): one number box per axis.
class Vec3Field extends Field {
  constructor(spec, emit) {
    const id = idFor(spec.ptr);
    super(spec, [spec.ptr], spec.label, `${id}-x`);
    this.axes = ['x', 'y', 'z'].map((axis) => h('input', {
      type: 'number', id: `${id}-${axis}`, class: `num axis axis-${axis}`, step: spec.step, inputmode: 'decimal',
      'aria-label': `${spec.label}, ${axis}`, title: axis,
    }));
    for (const input of this.axes) {
      input.addEventListener('change', () => {
        const v = this.axes.map((a) => num(a.value));
        if (!v.every(Number.isFinite)) { this.setError('Enter a number for each axis.'); return; }
        emit(this, patchAt(spec.ptr, v), true);
      });
    }
    this.describe(...this.axes);
    const cells = this.axes.map((input, i) => h('span', { class: 'axis-cell' },
      h('span', { class: 'axis-name', 'aria-hidden': 'true', text: 'xyz'[i] }), input));
    this.el.append(this.label, h('div', { class: 'row axes', role: 'group', 'aria-label': spec.label }, cells), this.error);
  }
  update(doc) {
    const v = getAt(doc, this.spec.ptr);
    if (!Array.isArray(v) || v.length !== 3) return;
    this.axes.forEach((a, i) => { if (!isEditing(a)) a.value = String(round(v[i], 5)); });
  }
}

// Fog density: writes equal extinction and scattering (a purely scattering fog).
class FogField extends Field {
  constructor(spec, emit) {
    const id = 'ctl-medium-density';
    super(spec, ['/medium/extinction', '/medium/scattering'], spec.label, id);
    this.range = h('input', { type: 'range', id, min: spec.min, max: spec.max, step: spec.step });
    this.number = h('input', { type: 'number', id: `${id}-num`, class: 'num', step: spec.step,
      inputmode: 'decimal', 'aria-label': `${spec.label}, exact value` });
    const patchFor = (v) => ({ medium: { extinction: [v, v, v], scattering: [v, v, v] } });
    this.range.addEventListener('input', () => {
      this.number.value = fmt(num(this.range.value), spec.step);
      emit(this, patchFor(num(this.range.value)), false);
    });
    this.range.addEventListener('change', () => emit(this, patchFor(num(this.range.value)), true));
    this.number.addEventListener('change', () => {
      const v = num(this.number.value);
      if (!Number.isFinite(v)) { this.setError('Enter a number.'); return; }
      this.range.value = String(v);
      emit(this, patchFor(v), true);
    });
    this.describe(this.number, this.range);
    this.el.append(this.label, h('div', { class: 'row' }, this.range, this.number), this.error);
  }
  update(doc) {
    const e = getAt(doc, '/medium/extinction');
    if (!Array.isArray(e)) return;
    const v = Math.max(...e);
    if (!isEditing(this.range)) this.range.value = String(v);
    if (!isEditing(this.number)) this.number.value = fmt(v, this.spec.step);
  }
}

// Example scenes, listed by the daemon (GET /api/examples); "Load" replaces the scene with one.
class ExampleField extends Field {
  constructor(spec, emit, hooks) {
    const id = 'ctl-example';
    super(spec, [], 'Example scene', id);
    this.select = h('select', { id }, h('option', { value: '', text: 'Choose an example…' }));
    this.button = h('button', { type: 'button', id: 'example-load', text: 'Load' });
    this.note = h('p', { class: 'note', id: `${id}-note`, 'aria-live': 'polite' });
    const load = () => { if (this.select.value) hooks.loadExample(this.select.value, this); };
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
function filePicker(id, accept, text, onFile) {
  const input = h('input', { type: 'file', id, accept, class: 'file-input' });
  input.addEventListener('change', () => {
    const f = input.files && input.files[0];
    if (f) onFile(f);
    input.value = '';
  });
  return { input, label: h('label', { for: id, class: 'button-like', text }) };
}

// Importing and exporting the scene document as a JSON file.
class SceneFileField extends Field {
  constructor(spec, emit, hooks) {
    const id = 'scene-file';
    super(spec, [], 'Scene document', id);
    const picker = filePicker(id, '.json,application/json', 'Import JSON…', (f) => hooks.importScene(f, this));
    this.file = picker.input;
    this.exportButton = h('button', { type: 'button', id: 'scene-export', text: 'Export JSON' });
    this.status = h('p', { class: 'note', id: 'scene-file-status', 'aria-live': 'polite' });
    this.exportButton.addEventListener('click', () => hooks.exportScene(this));
    // An animation (keyframes: a list of {time, patch}, as `refract animate` takes) played into this view.
    const play = filePicker('keyframes-file', '.json,application/json', 'Play keyframes…', (f) => hooks.playKeyframes(f, this));
    this.playFile = play.input;
    this.stopButton = h('button', { type: 'button', id: 'play-stop', text: 'Stop', hidden: true });
    this.stopButton.addEventListener('click', () => hooks.stopPlay());
    this.describe(this.file);
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
class MeshField extends Field {
  constructor(spec, emit, hooks) {
    const id = 'ctl-object-mesh';
    super(spec, ['/object/mesh'], 'Mesh', id);
    this.select = h('select', { id });
    this.builtin = h('optgroup', { label: 'Built-in' }, BUILTIN_MESHES.map(([v, t]) => h('option', { value: v, text: t })));
    this.uploaded = h('optgroup', { label: 'Uploaded', hidden: true });
    this.select.append(this.builtin, this.uploaded);
    this.select.addEventListener('change', () => emit(this, hooks.meshPatch(this.select.value), true));
    const picker = filePicker('mesh-file', '.obj,model/obj,text/plain', 'Upload OBJ…', (f) => hooks.upload(f, this));
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

// The outliner of one collection (lights or objects): which member the panel edits; members can be added,
// removed (all but the last) and renamed.
class MembersField extends Field {
  constructor(spec, emit, hooks) {
    const kind = spec.member;
    const id = `ctl-${kind}-member`;
    super(spec, [`/${kind}s`], spec.label, id);
    const members = hooks.members;
    this.kind = kind;
    this.hooks = members;
    this.select = h('select', { id, size: 2, class: 'member-list' });  // a list box: every member in view
    this.select.addEventListener('change', () => members.select(kind, this.select.value));
    this.addButton = h('button', { type: 'button', id: `${kind}-add`, text: 'Add' });
    this.removeButton = h('button', { type: 'button', id: `${kind}-remove`, text: 'Remove' });
    this.addButton.addEventListener('click', () => members.add(kind));
    this.removeButton.addEventListener('click', () => members.remove(kind));
    this.name = h('input', { type: 'text', id: `${kind}-name`, 'aria-label': `New name for the chosen ${kind}`, maxlength: 64,
      title: `New name for the chosen ${kind}`, placeholder: 'New name' });
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
    const names = Object.keys(doc[`${this.kind}s`] || {}).sort();
    const chosen = this.hooks.selected(this.kind);
    if (names.join('/') !== [...this.select.options].map((o) => o.value).join('/')) {
      this.select.replaceChildren(...names.map((n) => h('option', { value: n, text: n })));
      this.select.size = Math.max(2, Math.min(names.length, 6));
    }
    if (!isEditing(this.select)) this.select.value = chosen ?? '';
    if (!isEditing(this.name)) this.name.value = chosen ?? '';
    this.removeButton.disabled = names.length < 2;
  }
}

// Environment picker: the dark sky, a uniform colour or an image (built in or uploaded), plus an upload
// button for .hdr and .exr files.
class EnvironmentField extends Field {
  constructor(spec, emit, hooks) {
    const id = 'ctl-environment';
    super(spec, ['/environment/type', '/environment/image'],
      'Environment (seen past the scene and in reflections; a colour or an image lights the scene too)', id);
    this.select = h('select', { id }, [['sky', 'Dark sky'], ['uniform', 'Uniform colour']]
      .map(([v, t]) => h('option', { value: v, text: t })));
    this.images = h('optgroup', { label: 'Images', hidden: true });
    this.select.append(this.images);
    this.select.addEventListener('change', () => {
      const v = this.select.value;
      emit(this, { environment: v.startsWith('image:') ? { type: 'image', image: v.slice(6) } : { type: v } }, true);
    });
    const picker = filePicker('environment-file', '.hdr,.exr', 'Upload HDR/EXR…', (f) => hooks.uploadEnvironment(f, this));
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
  }
}

const KINDS = {
  range: RangeField, select: SelectField, checkbox: CheckboxField, color: ColorField, rgb: RgbField,
  fog: FogField, example: ExampleField, mesh: MeshField, file: SceneFileField, vec3: Vec3Field, members: MembersField,
  environment: EnvironmentField,
};

// Builds the panel into `form`. `onEdit(patch, final, field)` is called for every user edit.
export function buildControls(form, onEdit, hooks) {
  const fields = [];
  const emit = (field, patch, final) => {
    field.clearError();
    onEdit(patch, final, field);
  };
  for (const section of SECTIONS) {
    const fieldset = h('fieldset', { class: 'section', id: `section-${section.id}` }, h('legend', { text: section.title }));
    for (const spec of section.controls) {
      const field = new KINDS[spec.kind](spec, emit, hooks);
      fields.push(field);
      fieldset.append(field.el);
    }
    form.append(fieldset);
  }
  form.addEventListener('submit', (e) => e.preventDefault());

  return {
    fields,
    mesh: fields.find((f) => f instanceof MeshField),
    environment: fields.find((f) => f instanceof EnvironmentField),
    example: fields.find((f) => f instanceof ExampleField),
    file: fields.find((f) => f instanceof SceneFileField),
    outliners: fields.filter((f) => f instanceof MembersField),
    // Shows `doc` in every control, except those holding a rejected value the user has not fixed yet.
    update(doc, { force = false } = {}) {
      for (const f of fields) {
        if (force || !f.invalid || f.alwaysShows) f.update(doc);
        // Controls that the current settings ignore are hidden (never one that shows an error).
        if (f.spec.showIf) f.el.hidden = !f.invalid && !f.spec.showIf(doc);
      }
    },
    // The field whose pointer best matches an error pointer: exact, then the closest ancestor, then
    // the first field inside the pointer's subtree.
    fieldFor(pointer) {
      if (!pointer) return null;
      const tokens = parsePointer(pointer);
      for (let n = tokens.length; n > 0; --n) {
        const prefix = '/' + tokens.slice(0, n).join('/');
        const hit = fields.find((f) => f.ptrs.includes(prefix));
        if (hit) return hit;
      }
      return fields.find((f) => f.ptrs.some((p) => p.startsWith(pointer.endsWith('/') ? pointer : pointer + '/'))) || null;
    },
    clearErrors() { for (const f of fields) f.clearError(); },
    // Lowers a range control's maximum to what the daemon allows (from /api/health limits).
    setMax(ptr, max) {
      const f = fields.find((x) => x instanceof RangeField && x.spec.ptr === ptr);
      if (!f || !(max > 0)) return;
      const top = f.spec.toSlider ? Math.floor(f.spec.toSlider(max)) : max;
      if (top < Number(f.range.max)) f.range.max = String(top);
      f.number.max = String(max);
    },
  };
}

