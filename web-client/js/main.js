// Refract browser client: shows frames streamed by refractd and edits the scene with merge patches.
// This file wires the modules together and starts; README.md lists what each module owns.

import { environmentPatch, meshPatch, volumeGridsOf, volumeSwapSpot } from './catalog.js';
import { connect } from './connection.js';
import { $ } from './dom.js';
import {
  exportScene, importScene, loadExample, playKeyframes, savePng, uploadEnvironment, uploadMesh, uploadVolume,
} from './files.js';
import { initView } from './interaction.js';
import { members } from './outliner.js';
import { buildPanel } from './panel.js';
import { edit, link, saveView, setFollow, stopPlay } from './session.js';
import { hooks, panel, state, view } from './state.js';
import { stageMessage } from './status.js';

window.refract = hooks;  // read by the end-to-end test and the benchmark (README: Test hooks)

buildPanel($('controls'), edit, {
  uploadMesh, uploadEnvironment, uploadVolume, meshPatch, environmentPatch, volumeGrids: volumeGridsOf, volumeSwapSpot,
  loadExample, importScene, exportScene, playKeyframes, stopPlay, members, chosenVolume: () => panel().medium_volume,
  saveView, setFollow, following: () => state.follow, sceneCamera: () => view().camera,
});
initView();
$('save-png').addEventListener('click', savePng);

stageMessage('Connecting to refractd…');
connect(link);
