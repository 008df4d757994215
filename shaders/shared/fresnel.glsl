// Fresnel reflection at the object's boundary, shared by photons and eye rays (after transport_common.glsl).
//
// The smoothed index field has no surface, only a shell a few voxels thick where n climbs from the
// medium's index to the object's. A ray meets the boundary where its step crosses the shell's midpoint
// (TransportParams::shell.y, halfway between the two indices): the uniform object's n is the medium's
// plus its contrast times the smoothed coverage, which rises monotonically through the shell, so the
// midpoint is coverage 0.5, where the Gaussian (a voxel or two wide) leaves the mesh's surface, and it is
// crossed once per passage. The interface normal is grad n there. The two indices are the flat values
// either side of the shell, not the local n inside it; the angle of incidence on the incident side comes
// from n sin(theta), which a stratified shell conserves, so the ray's bending in the half shell it has
// already crossed does not change it. Reflecting the ray's direction about the normal at the start of
// the crossing step is exact for a locally flat shell: the reflected path is the mirror image of the
// incoming one and leaves the shell at the mirrored angle.
//
// Total internal reflection is the ray equation's: a stratified shell turns a ray back where n falls to
// n1 sin(theta1), which it reaches beyond the critical angle and not below it, whatever the smoothing.
// With Fresnel on, ray_step keeps n sin(theta) exactly across a stratified shell and shell steps
// shorten near a turning point (shell_step_for), so that a step cannot flip the ray's momentum along
// grad n: otherwise rays two degrees short of the critical angle came back a third too often. A ray
// whose n sin(theta) reaches the far side's index (or, turned back, the near side's) crosses no
// interface here. Deciding it here instead, with the flat-shell rule, trapped grazing rays in a
// sphere's curved shell for ever (its r n sin(psi) lets out every ray that got in; the flat rule does
// not).
//
// Graded fields (Luneburg, Maxwell) have no shell inside, only their outer boundary, where the analytic
// field meets the medium's index: shell.x is then the field's value there (the surface index), and as n
// rises inwards from it, the midpoint between it and the medium's is crossed at the boundary only, so
// nothing inside reflects. Where the surface index is not above the medium's (a Luneburg lens, a
// fish-eye of n0 <= 2 in air) Fresnel is off (transport_params.cpp, fresnel_reflects); imported grids
// have no boundary and never reflect.
//
// A thin film on the boundary (kFilm) replaces the interface's reflectance by the film's Airy reflectance
// between the same two indices, averaged over each channel's band (fresnel.h), with the film's thickness
// at the crossing's height (TransportParams::shell.zw, film.yz). The film's own index does not disperse.
#include "fresnel.h"

// The shell step for a ray: whole where its momentum along grad n, n cos(angle to grad n), is at least
// four times what a step changes it by (ds |grad n|), shorter nearer its turning point, down to a
// quarter (a ray skimming a shell would take too many shorter steps). Only with Fresnel on: without
// it no shell reflects, and steps stay as they were.
float shell_step_for(Ray ray, float shell_step) {
    if (!kFresnel) return shell_step;
    float contrast = kDispersive ? ray_contrast : 1.0;
    float g = contrast * length(ray.field.yzw);
    float n = params.medium_extinction.w + contrast * (ray.field.x - params.medium_extinction.w);
    float along = n * abs(dot(ray.d, ray.field.yzw)) * contrast / max(g, 1e-30);
    return clamp(0.25 * along / max(g, 1e-30), shell_step * 0.25, shell_step);
}

// The reflectance where a ray step from `before` to `after` crosses the object's boundary, per channel
// (the same in each without a film; under dispersion the ray's own channel, ray_contrast, is the one that
// counts), and the direction the reflected part leaves in; 0 where the step does not cross it.
vec3 shell_reflectance(Ray before, Ray after, out vec3 reflected) {
    reflected = before.d;
    // In a scene of several objects the boundary is that of the object whose shell the step starts in.
    Material object;
    if (kMaterials) {
        object = material_of(object_at(before));
        if (object.shell.x < 0.5) return vec3(0.0);  // its Fresnel is off
    }
    vec4 shell = kMaterials ? vec4(object.extinction.w, object.shell.yzw) : params.shell;
    vec4 film = kMaterials ? object.film : params.film;
    float midpoint = shell.y;
    bool entering = before.field.x < midpoint;
    vec3 g = before.field.yzw + after.field.yzw;
    float g_length = length(g);
    if (entering == (after.field.x < midpoint) || g_length == 0.0) return vec3(0.0);
    vec3 normal = g / g_length;
    float contrast = kDispersive ? ray_contrast : 1.0;
    float n_medium = params.medium_extinction.w;
    float n_object = n_medium + contrast * (shell.x - n_medium);
    float n_here = n_medium + contrast * (before.field.x - n_medium);
    float n1 = entering ? n_medium : n_object, n2 = entering ? n_object : n_medium;
    float cos_here = dot(before.d, normal);
    reflected = before.d - 2.0 * cos_here * normal;
    float across = n_here * sqrt(max(1.0 - cos_here * cos_here, 0.0));  // n sin(theta)
    if (across >= min(n1, n2)) return vec3(0.0);
    if (kFilm) {
        float height = clamp((shell.z - before.p.y) / max(shell.z - shell.w, 1e-6), 0.0, 1.0);
        float thickness = mix(film.y, film.z, height);
        if (thickness > 0.0) return film_band_reflectance(n1, film.x, n2, across / n1, thickness);
    }
    return vec3(fresnel_reflectance(n1, n2, across / n1));
}
