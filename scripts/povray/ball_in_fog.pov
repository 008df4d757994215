// The frame of examples/ball_lens_fog.json without its sky, for POV-Ray 3.7 (scripts/bench-povray.sh):
// a glass ball in a box of fog, lit by a hard-edged spot light, with photons for the volume caustic
// behind the ball (media photons) and the fog's single scattering by media sampling. POV-Ray is left-handed: z is the document's -z.
#version 3.7;
global_settings {
  assumed_gamma 1.0
  max_trace_level 10
  // As many photons as the document's 2^18 (POV-Ray shoots those that reach the ball), each storing up
  // to 100 media photons along its path through the fog.
  photons { count 262144 media 100 max_trace_level 10 }
}
camera { perspective location <0.4, 0.9, -5.2> look_at <0.4, 0, 0> right x up y angle 42 }
// Intensity falling as 1/r^2 (fade_power 2 with a short fade_distance), scaled to look like the
// document's 110 W/sr under its tone map: alike, not equal, pictures.
light_source { <-2.2, 0, 0> color rgb <1.0, 0.95, 0.85> * 100
  spotlight point_at <0, 0, 0> radius 9 falloff 9 tightness 0
  fade_distance 0.1 fade_power 2
  photons { refraction on reflection on } media_interaction on }
sphere { 0, 0.6
  pigment { rgbf <1, 1, 1, 1> }
  finish { ambient 0 diffuse 0 reflection { 0 1 fresnel on } conserve_energy }
  interior { ior 1.5 fade_distance 50 fade_power 1001 }
  photons { target refraction on reflection on collect off }
}
// The document's medium: extinction 0.25, scattering 0.24 (Henyey-Greenstein, g = 0.2), sampled along eye
// rays adaptively (method 3) from the fewest samples: 3 or 10 an interval changed neither the picture
// nor, at 3, the time (26 s at 1 and 3, 34 s at 10).
box { <-2.5, -2.6, -1.6>, <3.2, 2.6, 1.6>
  pigment { rgbt 1 } hollow
  interior { media { method 3 intervals 1 samples 1, 1
    scattering { 5, 0.24 eccentricity 0.2 extinction 1 } absorption 0.01 } }
  photons { pass_through }
}
