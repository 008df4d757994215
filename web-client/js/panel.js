// The control panel: built from one declarative table. Every control knows the JSON pointers it
// writes, so a validation error from the daemon (which names a pointer) lands next to its control.

import { $, h } from './dom.js';
import { CheckboxField, ColorField, FogField, RangeField, RgbField, SelectField, Vec3Field } from './fields.js';
import { EnvironmentField, ExampleField, MembersField, MeshField, SceneFileField, ViewField } from './pickers.js';
import { panelPointer, parsePointer } from './scene.js';
import { hooks, panel, state, view } from './state.js';
import { announce, showGlobalError } from './status.js';
import { EmissionIntensityField, EmitterField, VolumeAssetField, VolumeGridField } from './volumes.js';

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

// Whether the scene has a volume for the panel to edit.
const HAS_VOLUME = (doc) => typeof doc.medium_volume?.asset === 'string';
// Whether the chosen volume glows in a colour of its own (a plain emission grid, not a temperature).
const GLOWS_IN_COLOUR = (doc) => HAS_VOLUME(doc) && Boolean(doc.medium_volume.emission?.grid);

// The panel, section by section. A control's `kind` is its field class (KINDS below), `ptr` the pointer
// it writes; `showIf(doc)` hides it while the document ignores it; `limit` names the /api/health limit
// that lowers a range's maximum.
const SECTIONS = [
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
      { kind: 'range', ptr: '/object/ior', label: 'Index of refraction', short: 'IOR', min: 1, max: 4, step: 0.01,
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
        min: 0, max: 256, step: 16, limit: 'max_resolution' },
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
      { kind: 'range', ptr: '/medium/fade', label: 'Fog fade at the box\'s faces (m)', min: 0, max: 1, step: 0.01 },
      { kind: 'range', ptr: '/photons/max_bounces', label: 'Scattering bounces (0 = single scattering; previews take at most 4)',
        min: 0, max: 64, step: 1 },
      { kind: 'checkbox', ptr: '/floor/enabled', label: 'Floor' },
      { kind: 'checkbox', ptr: '/floor/checker', label: 'Checkered floor' },
    ],
  },
  {
    id: 'volumes', title: 'Volumes', controls: [
      { kind: 'volume-asset' },
      { kind: 'members', member: 'medium_volume', label: 'Volumes in the scene (the panel edits the one chosen)' },
      { kind: 'volume-grid', showIf: HAS_VOLUME },
      { kind: 'range', ptr: '/medium_volume/density_scale', label: 'Density scale', min: -2, max: 2, step: 0.01,
        ...LOG10_SLIDER, showIf: HAS_VOLUME },
      { kind: 'rgb', ptr: '/medium_volume/extinction', label: 'Extinction (per m at density 1)', min: 0, max: 50,
        step: 0.1, showIf: HAS_VOLUME },
      { kind: 'rgb', ptr: '/medium_volume/scattering', label: 'Scattering (per m at density 1; at most the extinction)',
        min: 0, max: 50, step: 0.1, showIf: HAS_VOLUME },
      { kind: 'range', ptr: '/medium_volume/phase/g', label: 'Volume anisotropy g', min: -0.95, max: 0.95, step: 0.01,
        showIf: HAS_VOLUME },
      { kind: 'emission-intensity', ptr: '/medium_volume/emission/intensity',
        label: 'Emission intensity (the light it gives off; 0 = none)', min: 0, max: 20, step: 0.1, showIf: HAS_VOLUME },
      { kind: 'emitter', label: 'Emitting grid (which of its grids glows, and how)', showIf: HAS_VOLUME },
      { kind: 'color', ptr: '/medium_volume/emission/color', label: 'Emission colour', showIf: GLOWS_IN_COLOUR },
      { kind: 'vec3', ptr: '/medium_volume/position', label: 'Position (m, of the file’s origin)', step: 0.05,
        showIf: HAS_VOLUME },
      { kind: 'range', ptr: '/medium_volume/scale', label: 'Volume scale', min: -3, max: 2, step: 0.01, ...LOG10_SLIDER,
        showIf: HAS_VOLUME },
      { kind: 'vec3', ptr: '/medium_volume/rotation_deg', label: 'Volume rotation (°, about x, then y, then z)', step: 5,
        showIf: HAS_VOLUME },
    ],
  },
  {
    id: 'environment', title: 'Environment', controls: [
      { kind: 'environment' },
      { kind: 'color', ptr: '/environment/color', label: 'Environment colour',
        showIf: (doc) => doc.environment?.type === 'uniform' },
      { kind: 'range', ptr: '/environment/intensity', label: 'Environment intensity', min: 0, max: 20, step: 0.001 },
      { kind: 'range', ptr: '/environment/rotation_deg', label: 'Environment rotation (° about the vertical)',
        min: -180, max: 180, step: 1, showIf: (doc) => doc.environment?.type === 'image' },
      { kind: 'checkbox', ptr: '/environment/lights', label: 'The environment lights the scene (off: a backdrop only)',
        showIf: (doc) => ['uniform', 'image'].includes(doc.environment?.type) },
    ],
  },
  {
    id: 'camera', title: 'Camera', controls: [
      { kind: 'view' },
      { kind: 'range', ptr: '/camera/fov_deg', label: 'Field of view (vertical, °)', min: 10, max: 120, step: 1 },
    ],
  },
  {
    id: 'quality', title: 'Quality', controls: [
      { kind: 'range', ptr: '/photons/count', label: 'Photons', min: 10, max: 22, step: 1, limit: 'max_photons',
        ...LOG2_SLIDER },
      { kind: 'range', ptr: '/volume/resolution', label: 'Volume resolution (voxels)', min: 32, max: 512, step: 16,
        limit: 'max_resolution' },
      { kind: 'range', ptr: '/image/exposure', label: 'Exposure (stops)', min: -4, max: 4, step: 0.1 },
    ],
  },
];

const KINDS = {
  range: RangeField, select: SelectField, checkbox: CheckboxField, color: ColorField, rgb: RgbField,
  fog: FogField, example: ExampleField, mesh: MeshField, file: SceneFileField, vec3: Vec3Field, members: MembersField,
  environment: EnvironmentField, view: ViewField, 'volume-asset': VolumeAssetField, 'volume-grid': VolumeGridField,
  'emission-intensity': EmissionIntensityField, emitter: EmitterField,
};

// The panel once built (buildPanel, from main.js before anything else runs).
export let controls = null;

// Builds the panel into `form` and sets `controls`. `onEdit(patch, final, field)` is called for every user
// edit; `actions` are what the pickers do (see pickers.js).
export function buildPanel(form, onEdit, actions) {
  const fields = [];
  const emit = (field, patch, final) => {
    field.clearError();
    onEdit(patch, final, field);
  };
  for (const section of SECTIONS) {
    const fieldset = h('fieldset', { class: 'section', id: `section-${section.id}` }, h('legend', { text: section.title }));
    for (const spec of section.controls) {
      const field = new KINDS[spec.kind](spec, emit, actions);
      fields.push(field);
      fieldset.append(field.el);
    }
    form.append(fieldset);
  }
  form.addEventListener('submit', (e) => e.preventDefault());

  controls = {
    mesh: fields.find((f) => f instanceof MeshField),
    environment: fields.find((f) => f instanceof EnvironmentField),
    example: fields.find((f) => f instanceof ExampleField),
    file: fields.find((f) => f instanceof SceneFileField),
    volumes: fields.find((f) => f instanceof VolumeAssetField),
    outliners: fields.filter((f) => f instanceof MembersField),
    // Shows `doc` in every control, except those holding a rejected value the user has not fixed yet.
    update(doc) {
      for (const f of fields) {
        f.update(doc);
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
    // Lowers the range controls' maxima to what the daemon allows (`limits` from /api/health).
    setLimits(limits) {
      for (const f of fields) {
        const max = f.spec.limit && Number(limits[f.spec.limit]);
        if (!(max > 0)) continue;
        const top = f.spec.toSlider ? Math.floor(f.spec.toSlider(max)) : max;
        if (top < Number(f.range.max)) f.range.max = String(top);
        f.number.max = String(max);
        f.fitNumber([f.number.dataset.widest || '', String(max)]);
      }
    },
  };
}

// ---- complaints: errors shown at the control they are about ------------------------------------

// A rule as the daemon words it ("must be a number in [1, 4]") as a person would ("must be between 1
// and 4"); other rules as they are.
function wordRule(rule) {
  const n = (x) => (Number.isFinite(Number(x)) ? String(Number(x)) : x);
  const m = /^must be an? (number|integer) in ([[(])([^,]+), ([^\])]+)([\])])(.*)$/.exec(rule || '');
  if (!m) return rule;
  const [, kind, open, lo, hi, close, rest] = m;
  const whole = kind === 'integer' ? ' (a whole number)' : '';
  if (open === '[' && close === ']') return `must be between ${n(lo)} and ${n(hi)}${whole}${rest}`;
  const from = open === '[' ? `at least ${n(lo)}` : `more than ${n(lo)}`;
  const to = close === ']' ? `at most ${n(hi)}` : `less than ${n(hi)}`;
  return `must be ${from} and ${to}${whole}${rest}`;
}

// The name a field's errors go by: its short name, else its label up to any explanation.
const fieldName = (field) => field.spec.short || (field.label?.textContent || field.spec.label || '').split(/ \(|:/)[0];

// A daemon's error, shown under the control that writes its pointer (the closest one), in words
// ("IOR must be between 1 and 4"; the pointer and the daemon's own words in its tooltip), the control
// back at the scene's value; else in the banner.
export function reportError(message, daemonPointer, seq = null, rule = null) {
  const pointer = daemonPointer && panelPointer(daemonPointer, view(), state.selected);
  hooks.lastError = { error: message, pointer: pointer ?? null, seq };
  hooks.errors++;
  const field = controls.fieldFor(pointer);
  if (field) {
    const name = fieldName(field);
    field.setError(rule && name ? `${name} ${wordRule(rule)}` : message, pointer ? `${pointer}: ${rule || message}` : '');
    field.update(panel(), true);
    if (field.el.getBoundingClientRect().height > 0) field.el.scrollIntoView({ block: 'nearest' });
  } else {
    showGlobalError(pointer ? `${message} (${pointer})` : message);
  }
  announce(`Error${pointer ? ` in ${pointer}` : ''}: ${message}`);
}

// A failed action (an upload, a name refused, a file that is not a scene) said at `field`; `pointer` is
// what the test hooks blame.
export function complain(field, message, pointer, spoken = message) {
  field.setError(message);
  hooks.lastError = { error: message, pointer, seq: null };
  hooks.errors++;
  announce(spoken);
}

// An accepted edit makes earlier complaints stale: a failed upload, a refused Add, Remove or Rename, a
// frame that could not render.
export function clearComplaints() {
  for (const outliner of controls.outliners) outliner.clearError();
  controls.mesh.clearError();
  controls.volumes.clearError();
  controls.file.clearError();
  controls.file.status.textContent = '';
  $('global-error').hidden = true;
}
