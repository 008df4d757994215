// Example scenes, each a JSON merge patch over whatever scene is loaded. Every preset writes all the
// fields it cares about (object, light, medium, floor, camera) so the result does not depend on the
// previous scene; quality settings (image, volume resolution, photons) are left as the user set them.

import { normalize, roundVec, sub } from './scene.js';

const aim = (position, target = [0, 0, 0]) => roundVec(normalize(sub(target, position)));

const spot = (position, { target = [0, 0, 0], color = [1, 1, 1], intensity = 30, cone = 22 } = {}) => ({
  type: 'spot', position, direction: aim(position, target), color, intensity, cone_deg: cone,
});

const clearPhase = { model: 'isotropic', g: 0 };
const object = (fields) => ({
  mesh: 'sphere', position: [0, 0, 0], rotation_deg: [0, 0, 0], scale: 1, index_field: 'uniform', ior: 1.5, abbe: 0,
  extinction: [0.02, 0.02, 0.02], scattering: [0, 0, 0], phase: clearPhase, ...fields,
});
const medium = (density, g = 0.3) => ({
  ior: 1, extinction: [density, density, density], scattering: [density, density, density],
  phase: { model: 'henyey-greenstein', g },
});
const camera = (position, target = [0, -0.2, 0]) => ({ position, target, up: [0, 1, 0], fov_deg: 40 });
// The volume's framing: metres of fog around the object that photons light (the document's default 0.35).
const framing = (margin = 0.35) => ({ margin });

export const PRESETS = [
  {
    id: 'ball-lens-fog',
    name: 'Ball lens in fog',
    description: 'A glass sphere focuses a spot light into a bright caustic cone through light fog.',
    patch: {
      camera: camera([0.3, 0.5, 4.4]),
      light: spot([0.4, 3.2, 0.3], { color: [1, 0.95, 0.85], intensity: 40, cone: 18 }),
      object: object({ mesh: 'sphere', scale: 0.6, position: [0, 0.2, 0], ior: 1.5 }),
      medium: medium(0.25, 0.4),
      floor: { enabled: true, height: -1, albedo: [0.8, 0.8, 0.8], checker: false },
      volume: framing(),
    },
  },
  {
    id: 'dispersive-ball',
    name: 'Dispersive glass ball',
    description: 'A glass ball with exaggerated dispersion (Abbe number 8; flint glass is about 30) splits a white beam: blue focuses first, and the cone behind the focus is fringed with colour.',
    patch: {
      camera: camera([0.4, 0.9, 5.2], [0.4, 0, 0]),
      light: spot([-2.2, 0, 0], { target: [1, 0, 0], intensity: 110, cone: 9 }),
      object: object({ mesh: 'sphere', scale: 0.6, ior: 1.6, abbe: 8 }),
      medium: medium(0.25, 0.2),
      floor: { enabled: false, height: -1, albedo: [0.8, 0.8, 0.8], checker: false },
      volume: framing(1.0),  // room for the beam to narrow to its focus and open again
    },
  },
  {
    id: 'prism',
    name: 'Dispersing prism',
    description: 'A glass prism (Abbe number 10, exaggerated) fans a narrow white beam out into a spectrum on the floor.',
    patch: {
      camera: camera([0.6, 0.6, 5.0], [0.6, -0.3, 0]),
      light: spot([-2.6, 0.15, 0], { target: [1, 0.15, 0], intensity: 400, cone: 3 }),
      object: object({ mesh: 'prism', scale: 0.6, rotation_deg: [0, 0, -18], ior: 1.6, abbe: 10 }),
      medium: medium(0.15, 0.2),
      floor: { enabled: true, height: -1, albedo: [0.8, 0.8, 0.8], checker: false },
      volume: framing(1.2),  // room for the fan to reach the floor
    },
  },
  {
    id: 'luneburg-lens',
    name: 'Luneburg lens',
    description: 'A graded-index sphere (n = √(2 − r²)) bends a light from the side to a focus on its far surface.',
    patch: {
      camera: camera([0, 1.4, 4.2]),
      light: spot([-3.2, 0.3, 0], { intensity: 45, cone: 16 }),
      object: object({ mesh: 'sphere', scale: 0.8, index_field: 'luneburg', extinction: [0.01, 0.01, 0.01] }),
      medium: medium(0.18, 0.5),
      floor: { enabled: true, height: -1, albedo: [0.7, 0.7, 0.75], checker: true },
      volume: framing(),
    },
  },
  {
    id: 'glass-torus-floor',
    name: 'Glass torus over a floor',
    description: 'A tilted glass ring casts curved caustics on a checker floor.',
    patch: {
      camera: camera([0.9, 1.9, 4.6], [0, -0.45, 0]),
      light: spot([1.2, 3.4, 0.6], { intensity: 35, cone: 25 }),
      object: object({ mesh: 'torus', position: [0, -0.2, 0], rotation_deg: [62, 0, 18], scale: 0.65, ior: 1.52 }),
      medium: medium(0.05, 0.3),
      floor: { enabled: true, height: -1, albedo: [0.85, 0.85, 0.85], checker: true },
      volume: framing(),
    },
  },
  {
    id: 'absorbing-cube',
    name: 'Coloured absorbing cube',
    description: 'A cube that absorbs red and green strongly: the light through it and its shadow turn blue-violet.',
    patch: {
      camera: camera([2.2, 1.2, 3.6]),
      light: spot([-1.5, 3.4, 1.2], { color: [1, 1, 1], intensity: 35, cone: 24 }),
      object: object({
        mesh: 'cube', rotation_deg: [20, 35, 0], scale: 0.6, ior: 1.45,
        extinction: [2.4, 1.6, 0.25], scattering: [0.2, 0.2, 0.2], phase: { model: 'henyey-greenstein', g: 0.2 },
      }),
      medium: medium(0.12, 0.3),
      floor: { enabled: true, height: -1, albedo: [0.85, 0.85, 0.85], checker: true },
      volume: framing(),
    },
  },
  {
    id: 'maxwell-fisheye',
    name: 'Maxwell fish-eye',
    description: 'A fish-eye index field images each point of the sphere surface onto the opposite point.',
    patch: {
      camera: camera([0, 0.8, 4.2]),
      light: spot([2.6, 1.8, 1.2], { intensity: 40, cone: 14 }),
      object: object({ mesh: 'sphere', scale: 0.8, index_field: 'maxwell', extinction: [0.01, 0.01, 0.01] }),
      medium: medium(0.2, 0.5),
      floor: { enabled: true, height: -1, albedo: [0.8, 0.8, 0.8], checker: false },
      volume: framing(),
    },
  },
];
