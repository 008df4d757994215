// The Volumes section's own fields: the volume's file and its density grid.

import { h } from './dom.js';
import { Field, isEditing } from './fields.js';
import { filePicker } from './pickers.js';

// Volumes (OpenVDB smoke and clouds): the uploaded files, showing the chosen volume's (with none in the
// scene, the one Add places; choosing another gives the chosen volume that file), and an upload button.
export class VolumeAssetField extends Field {
  constructor(spec, emit, actions) {
    const id = 'ctl-medium-volume-asset';
    super(spec, ['/medium_volume/asset'], 'Volume file (OpenVDB: smoke, clouds)', id);
    this.select = h('select', { id });
    this.select.addEventListener('change', () => {
      const asset = this.select.value;
      if (actions.members.selected('medium_volume') === null) return;
      emit(this, { medium_volume: { asset, grid: actions.volumeGrids(asset)[0] ?? 'density' } }, true);
    });
    const picker = filePicker('volume-file', '.vdb', 'Upload VDB…', (f) => actions.uploadVolume(f, this));
    this.status = h('p', { class: 'note', id: 'volume-status', 'aria-live': 'polite' });
    this.describe(this.select, picker.input);
    this.el.append(this.label, h('div', { class: 'row' }, this.select, picker.input, picker.label), this.status,
      this.error);
  }
  setVolumes(names) {
    const current = this.select.value;
    this.select.replaceChildren(...names.map((n) => h('option', { value: n, text: n })));
    if (names.includes(current)) this.select.value = current;
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
    const names = grids.includes(want) ? grids : [...grids, want];
    if (names.join('/') !== [...this.select.options].map((o) => o.value).join('/')) {
      this.select.replaceChildren(...names.map((n) => h('option', { value: n, text: n })));
    }
    if (force || !isEditing(this.select)) this.select.value = want;
  }
}
