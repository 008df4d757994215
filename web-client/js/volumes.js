// The Volumes section's own fields: the volume (built in, or an uploaded OpenVDB file), its density grid
// and its emission (how brightly it glows, and which grid glows); and the rules that keep a volume's grid
// names valid as they change, so that picking a file, a grid or an intensity is never refused (422): the
// daemon takes an emission above 0 only with exactly one grid of the volume's own named.

import { h } from './dom.js';
import { Field, RangeField, isEditing } from './fields.js';
import { filePicker } from './pickers.js';

const BUILTIN = 'builtin.';

// How the pickers name a volume: an upload by its name, a built-in one in words ("Cloud (built-in)").
const volumeLabel = (name) => (name.startsWith(BUILTIN)
  ? `${name.charAt(BUILTIN.length).toUpperCase()}${name.slice(BUILTIN.length + 1)} (built-in)` : name);

// The density grid of a volume of a file with usable grids `grids`: `density` where it has one (or its
// grids are not known yet), else its first.
const densityGrid = (grids) => (grids.length && !grids.includes('density') ? grids[0] : 'density');

// A new volume of file `asset` (usable grids `grids`) whole, as the daemon would fill it in
// (protocol/README.md, volumes), at `spot` ({scale, position, density_scale}; {}: where its file puts it): the panel shows
// what it is sent, and would leave blank what it lacked.
export const newVolume = (asset, grids, spot) => ({
  asset, grid: densityGrid(grids), position: [0, 0, 0], rotation_deg: [0, 0, 0], scale: 1, density_scale: 1, ...spot,
  extinction: [1, 1, 1], scattering: [1, 1, 1], phase: { model: 'henyey-greenstein', g: 0 },
  emission: { grid: '', temperature_grid: '', color: [1, 1, 1], intensity: 0 },
});

// What starts to glow in a volume of usable grids `grids` whose density is grid `density`: its `temperature`
// grid as a blackbody (a flame's), else its first other grid in the colour chosen, else its density.
function defaultEmitter(grids, density) {
  if (grids.includes('temperature')) return { grid: '', temperature_grid: 'temperature' };
  return { grid: grids.find((g) => g !== density) ?? density, temperature_grid: '' };
}

// The emission grids that make `member` (a volume as an edit will leave it) valid for a file of usable
// grids `grids`, or null when its own do (or the file's grids are not known yet, when the daemon judges).
// A grid the file lacks (one of the member's earlier file) is dropped; while the volume glows, the file's
// default emitter takes its place.
function emitterFor(member, grids) {
  const emission = member.emission || {};
  const named = emission.temperature_grid || emission.grid;
  if (!grids.length || (named && grids.includes(named))) return null;
  if (emission.intensity > 0) return defaultEmitter(grids, member.grid ?? 'density');
  return named ? { grid: '', temperature_grid: '' } : null;
}

// The chosen volume (the panel's `medium_volume`) and the usable grids of its file, from the panel's actions.
function chosen(actions) {
  const member = actions.chosenVolume();
  return { member, grids: actions.volumeGrids(member.asset) };
}

// Gives `parent` (a select or an option group) the options `[value, text]`, rebuilt only when they differ,
// so that a list the user has open stays open.
function setOptions(parent, options) {
  if (options.map(([v]) => v).join('\n') === [...parent.children].map((o) => o.value).join('\n')) return;
  parent.replaceChildren(...options.map(([value, text]) => h('option', { value, text })));
}

// The volumes the daemon offers, uploads first, then the built-in ones (so that a scene without uploads
// adds one of those), showing the chosen volume's; choosing another gives the chosen volume that file,
// with its density grid, standing where it stood as large (a flame in place of a cloud would otherwise
// take the cloud's scale), and keeps its emission to grids the file has. With none in the scene, the one
// shown is what Add places. An upload button beside it.
export class VolumeAssetField extends Field {
  constructor(spec, emit, actions) {
    const id = 'ctl-medium-volume-asset';
    super(spec, ['/medium_volume/asset'], 'Volume (built in, or an uploaded OpenVDB file of smoke or clouds)', id);
    this.select = h('select', { id });
    this.select.addEventListener('change', () => {
      const asset = this.select.value;
      if (actions.members.selected('medium_volume') === null) return;
      const grids = actions.volumeGrids(asset);
      const grid = densityGrid(grids);
      const { member } = chosen(actions);
      const emission = emitterFor({ ...member, grid }, grids);
      const spot = actions.volumeSwapSpot(member, asset);
      emit(this, { medium_volume: { asset, grid, ...spot, ...(emission && { emission }) } }, true);
    });
    const picker = filePicker('volume-file', '.vdb,.nvdb', 'Upload VDB…', (f) => actions.uploadVolume(f, this));
    this.status = h('p', { class: 'note', id: 'volume-status', 'aria-live': 'polite' });
    this.describe(this.select, picker.input);
    this.el.append(this.label, h('div', { class: 'row' }, this.select, picker.input, picker.label), this.status,
      this.error);
  }
  setVolumes(uploads, builtins) {
    const current = this.select.value;
    setOptions(this.select, [...uploads, ...builtins].map((n) => [n, volumeLabel(n)]));
    if ([...this.select.options].some((o) => o.value === current)) this.select.value = current;
  }
  setStatus(text) { this.status.textContent = text; }
  update(doc) {
    const v = doc.medium_volume?.asset;
    if (typeof v === 'string' && !isEditing(this.select) && [...this.select.options].some((o) => o.value === v)) {
      this.select.value = v;
    }
  }
}

// The grid of the chosen volume's file that is its density: one of the file's usable float grids.
export class VolumeGridField extends Field {
  constructor(spec, emit, actions) {
    const id = 'ctl-medium-volume-grid';
    super(spec, ['/medium_volume/grid'], 'Density grid', id);
    this.gridsOf = actions.volumeGrids;
    this.select = h('select', { id });
    this.select.addEventListener('change', () => emit(this, { medium_volume: { grid: this.select.value } }, true));
    this.describe(this.select);
    this.el.append(this.label, this.select, this.error);
  }
  update(doc, force = false) {
    const member = doc.medium_volume || {};
    const want = member.grid ?? 'density';
    const grids = this.gridsOf(member.asset);
    setOptions(this.select, (grids.includes(want) ? grids : [...grids, want]).map((n) => [n, n]));
    if (force || !isEditing(this.select)) this.select.value = want;
  }
}

// How brightly the chosen volume glows (0: not at all). Raised above 0 while no grid of its file glows,
// it names the default one (emitterFor) in the same edit.
export class EmissionIntensityField extends RangeField {
  constructor(spec, emit, actions) {
    super(spec, (field, patch, final) => {
      const { member, grids } = chosen(actions);
      const { intensity } = patch.medium_volume.emission;
      const emitter = emitterFor({ ...member, emission: { ...member.emission, intensity } }, grids);
      emit(field, emitter ? { medium_volume: { emission: { intensity, ...emitter } } } : patch, final);
    });
  }
}

// Option values of the emitting grid: none, or a grid read as kelvin or as a glow in the colour chosen.
const KELVIN = 'k:';
const GLOW = 'c:';

// Which grid of the chosen volume's file glows: none, or one of its usable grids read as a temperature in
// kelvin (glowing in its blackbody colour) or as a glow in the colour chosen. Picking one names it and
// clears the other kind in one edit, and turns a volume that does not glow yet on at intensity 1, so the
// choice shows; None turns it off.
export class EmitterField extends Field {
  constructor(spec, emit, actions) {
    const id = 'ctl-medium-volume-emitter';
    super(spec, ['/medium_volume/emission/grid', '/medium_volume/emission/temperature_grid'], spec.label, id);
    this.gridsOf = actions.volumeGrids;
    this.select = h('select', { id });
    this.kelvin = h('optgroup', { label: 'A temperature in kelvin: glows in its blackbody colour' });
    this.glow = h('optgroup', { label: 'A glow in the emission colour, as bright as the grid’s value' });
    this.select.append(h('option', { value: '', text: 'None (it does not glow)' }), this.kelvin, this.glow);
    this.select.addEventListener('change', () => {
      const v = this.select.value;
      const name = v.slice(2);
      if (!v) return emit(this, { medium_volume: { emission: { intensity: 0, grid: '', temperature_grid: '' } } }, true);
      const on = chosen(actions).member.emission?.intensity > 0 ? {} : { intensity: 1 };
      const grids = v.startsWith(KELVIN) ? { grid: '', temperature_grid: name } : { grid: name, temperature_grid: '' };
      emit(this, { medium_volume: { emission: { ...grids, ...on } } }, true);
    });
    this.describe(this.select);
    this.el.append(this.label, this.select, this.error);
  }
  update(doc, force = false) {
    const member = doc.medium_volume || {};
    const { grid = '', temperature_grid: kelvin = '' } = member.emission || {};
    const grids = this.gridsOf(member.asset);
    const named = grid || kelvin;
    const names = !named || grids.includes(named) ? grids : [...grids, named];
    setOptions(this.kelvin, names.map((n) => [`${KELVIN}${n}`, `${n} (blackbody, K)`]));
    setOptions(this.glow, names.map((n) => [`${GLOW}${n}`, `${n} × colour`]));
    if (force || !isEditing(this.select)) this.select.value = kelvin ? `${KELVIN}${kelvin}` : grid ? `${GLOW}${grid}` : '';
  }
}
