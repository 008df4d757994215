// The panel's fields that hold a value of the document: each knows the JSON pointers it writes, shows
// the document's value there and reports edits as merge patches.

import { h } from './dom.js';
import { getAt, hexToLinear, linearToHex, patchAt, round } from './scene.js';

const idFor = (ptr) => 'ctl' + ptr.replace(/[^a-z0-9]+/gi, '-');
const num = (value) => (value === '' || value === null || value === undefined ? NaN : Number(value));
export const isEditing = (el) => el && document.activeElement === el;

function fmt(value, step, format) {
  if (typeof value !== 'number' || !Number.isFinite(value)) return '';
  if (format) return format(value);
  const digits = step >= 1 ? 0 : Math.min(4, Math.max(1, Math.ceil(-Math.log10(step))));
  return String(round(value, digits));
}

// Base: a labelled field with an inline error slot.
export class Field {
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
  // Shows `message` under the field; `detail` (the daemon's JSON pointer and rule) as its tooltip.
  setError(message, detail = '') {
    this.invalid = true;
    this.el.classList.add('invalid');
    this.error.textContent = message;
    this.error.title = detail;
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
  update() {}
}

export class RangeField extends Field {
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
    const value = (r) => (spec.fromSlider ? spec.fromSlider(r) : r);
    this.fitNumber([spec.min, spec.max, spec.max - spec.step].map((r) => fmt(value(r), this.numberStep(), spec.format)));
  }
  // Widens the exact-value box to show the longest of `texts` (its range's ends) whole.
  fitNumber(texts) {
    const widest = texts.reduce((a, b) => (b.length > a.length ? b : a), '');
    this.number.dataset.widest = widest;
    this.number.style.width = `max(5.6em, calc(${widest.length}ch + 2.8em))`;
  }
  numberStep() { return this.spec.numberStep ?? this.spec.step; }
  setRange(v) { this.range.value = String(this.spec.toSlider ? this.spec.toSlider(v) : v); }
  // `force`: even into the input being edited (a refused value goes back to the scene's).
  update(doc, force = false) {
    const v = getAt(doc, this.spec.ptr);
    if (typeof v !== 'number') return;
    if (force || !isEditing(this.range)) this.setRange(v);
    if (force || !isEditing(this.number)) this.number.value = fmt(v, this.numberStep(), this.spec.format);
  }
}

export class SelectField extends Field {
  constructor(spec, emit) {
    const id = idFor(spec.ptr);
    super(spec, [spec.ptr], spec.label, id);
    this.select = h('select', { id }, spec.options.map(([v, t]) => h('option', { value: v, text: t })));
    this.select.addEventListener('change', () => emit(this, patchAt(spec.ptr, this.select.value), true));
    this.describe(this.select);
    this.el.append(this.label, this.select, this.error);
  }
  update(doc, force = false) {
    const v = getAt(doc, this.spec.ptr);
    if (typeof v === 'string' && (force || !isEditing(this.select))) this.select.value = v;
  }
}

export class CheckboxField extends Field {
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

export class ColorField extends Field {
  constructor(spec, emit) {
    const id = idFor(spec.ptr);
    super(spec, [spec.ptr], spec.label, id);
    this.picker = h('input', { type: 'color', id, value: '#ffffff' });
    this.picker.addEventListener('input', () => emit(this, patchAt(spec.ptr, hexToLinear(this.picker.value)), false));
    this.picker.addEventListener('change', () => emit(this, patchAt(spec.ptr, hexToLinear(this.picker.value)), true));
    this.describe(this.picker);
    this.el.append(h('div', { class: 'row' }, this.label, this.picker), this.error);
  }
  update(doc, force = false) {
    const v = getAt(doc, this.spec.ptr);
    if (Array.isArray(v) && (force || !isEditing(this.picker))) this.picker.value = linearToHex(v);
  }
}

// An RGB coefficient: one slider that sets all channels, plus an exact number per channel.
export class RgbField extends Field {
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
  update(doc, force = false) {
    const v = getAt(doc, this.spec.ptr);
    if (!Array.isArray(v) || v.length !== 3) return;
    this.channels.forEach((c, i) => { if (force || !isEditing(c)) c.value = fmt(v[i], this.spec.step); });
    if (force || !isEditing(this.all)) this.all.value = String(Math.max(...v));
    this.all.setAttribute('aria-valuetext', v.map((x) => fmt(x, this.spec.step)).join(', '));
  }
}

// A vec3 (position, rotation): one number box per axis.
export class Vec3Field extends Field {
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
  update(doc, force = false) {
    const v = getAt(doc, this.spec.ptr);
    if (!Array.isArray(v) || v.length !== 3) return;
    this.axes.forEach((a, i) => { if (force || !isEditing(a)) a.value = String(round(v[i], 5)); });
  }
}

// Fog density: writes equal extinction and scattering (a purely scattering fog).
export class FogField extends Field {
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
  update(doc, force = false) {
    const e = getAt(doc, '/medium/extinction');
    if (!Array.isArray(e)) return;
    const v = Math.max(...e);
    if (force || !isEditing(this.range)) this.range.value = String(v);
    if (force || !isEditing(this.number)) this.number.value = fmt(v, this.spec.step);
  }
}
