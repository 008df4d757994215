// The outliners' actions (their lists are pickers.js's MembersField): which light and object the panel
// edits, and adding, removing and renaming them.

import { besideChosen, chosenVolumeAsset, volumeGridsOf, volumeSpot } from './catalog.js';
import { complain, controls } from './panel.js';
import * as S from './scene.js';
import { edit, showDocument } from './session.js';
import { panel, state, view } from './state.js';
import { announce } from './status.js';
import { newVolume } from './volumes.js';

// What Add puts in the scene, by kind: a point light beside the others; a small sphere beside the chosen
// object (so it is in view), sharing its Abbe number as the daemon requires; the volume shown in the picker
// (built in or uploaded; none: null), beside the chosen object too, sized by its own box (at the origin it
// would sit inside the default glass sphere).
const NEW_MEMBER = {
  medium_volume: (doc) => {
    const asset = chosenVolumeAsset();
    return asset && newVolume(asset, volumeGridsOf(asset), volumeSpot(asset, doc));
  },
  light: () => ({ type: 'point', position: [-2, 2.5, 1.5], intensity: 10 }),
  object: (doc) => {
    const chosen = doc.object || {};
    return { mesh: 'sphere', ...besideChosen(doc), abbe: chosen.abbe ?? 0 };
  },
};
const ARTICLE = { light: 'a', object: 'an', medium_volume: 'a' };

function selected(kind) {
  return S.selectedName(view(), kind, state.selected[kind]);
}

function select(kind, name) {
  state.selected[kind] = name;
  controls.clearErrors();
  showDocument(true);
}

function add(kind) {
  const noun = S.MEMBER_NOUN[kind];
  const member = NEW_MEMBER[kind](panel());
  const outliner = controls.outliners.find((f) => f.kind === kind);
  if (!member) return void complain(outliner, `Upload a ${noun} first: the daemon offers none.`, `/${S.COLLECTIONS[kind]}`);
  const name = S.freeName(view(), kind, noun);
  edit({ [S.COLLECTIONS[kind]]: { [name]: member } }, true);
  select(kind, name);
  announce(`Added ${ARTICLE[kind]} ${noun}, ${name}`);
}

function remove(kind) {
  const name = selected(kind);
  if (!name || S.memberNames(view(), kind).length <= S.MIN_MEMBERS[kind]) return;
  edit({ [S.COLLECTIONS[kind]]: { [name]: null } }, true);
  select(kind, null);
  announce(`Removed the ${S.MEMBER_NOUN[kind]} ${name}`);
}

// A rename is one patch: the member under its new name, null under its old one. A name the daemon would
// refuse is said at the outliner, and nothing is sent.
function rename(kind, to, field) {
  const from = selected(kind);
  if (!from || to === from) return;
  const refuse = (message) => complain(field, message, field.ptrs[0]);
  if (!S.validName(to)) return void refuse(`“${to}” is not a name: use 1 to 64 letters, digits, “_”, “.” or “-” (not “.” or “..”).`);
  if (S.memberNames(view(), kind).includes(to)) return void refuse(`There is already ${ARTICLE[kind]} ${S.MEMBER_NOUN[kind]} named “${to}”.`);
  const plural = S.COLLECTIONS[kind];
  edit({ [plural]: { [from]: null, [to]: view()[plural][from] } }, true);
  select(kind, to);
  announce(`Renamed the ${S.MEMBER_NOUN[kind]} ${from} to ${to}`);
}

// What the outliners' lists and buttons do (the panel's `actions.members`).
export const members = { selected, select, add, remove, rename };
