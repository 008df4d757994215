// Photon random walks (multiple scattering, photons.max_bounces): where a photon scatters along its
// curved path, and where it goes then. Needs transport_common.glsl (params) and phase.h.
//
// Free paths through the homogeneous medium and the objects are sampled by ray marching the optical
// depth: the photon loop already integrates extinction step by step (Beer-Lambert with each step's
// coefficients), and a free path drawn as an optical depth -ln(1 - xi) and spent along those same steps
// is exact for that piecewise-constant extinction, so a walk sees the very medium a photon of today's
// single-scattering transport sees; where coefficients change, steps are a voxel long (refracting shells,
// and walk_step where n does not change with them) and take the mean of their ends' coefficients. The
// volumes' scattering, which varies within a step, is sampled apart by delta tracking against the
// majorant of the step's block of the medium field (its most extinction, which bounds its scattering):
// tentative collisions at rate mu along the step, each real with probability sigma_s(x) / mu at its own
// point, so the volumes' collisions come exactly where their field puts them, not at a step's midpoint
// value. The two are independent Poisson processes; the first collision of either ends the step.
//
// Collisions are sampled against the channels' mean scattering coefficient sigma (per voxel), not the
// extinction: a photon's weight takes absorption continuously, exp(-(kappa_c - sigma) s) per channel,
// and at a scattering event each channel's weight is multiplied by sigma_s,c / sigma (1 for grey
// scattering). The expected weight of every channel is then that of an analog walk with albedo
// sigma_s,c / kappa_c (unbiased), absorbing glass that does not scatter is crossed with today's
// Beer-Lambert weights and no collisions at all, and no photon is killed by absorption: what a walk
// loses to it, the track-length deposits count. After its last allowed bounce a photon goes on as
// today's photons do, attenuated by the whole extinction.
struct Walk {
    float depth_left;  // optical depth (against sigma) still to go before the next scattering event
    uint bounces;      // scattering events so far
    bool collides;     // the step being taken ends at a scattering event
    bool by_field;     // ... of the volumes' (delta tracking), else of the medium's or an object's
    float coverage;    // the coverage of that step's coefficients
    uint object;       // and the object whose they are (object_at)
    float density;     // and the medium's density over it (medium_density)
    vec4 field;        // and the volumes' scattering where it collided (field_scattering; kMediumField)
    uint rng;          // the delta tracking's own random stream
};

// A walk before its first free path: `xi` uniform in [0, 1), `seed` its delta tracking's stream.
Walk start_walk(float xi, uint seed) { return Walk(-log(1.0 - xi), 0u, false, false, 0.0, 0u, 1.0, vec4(0.0), seed); }


// Delta tracking of the volumes' scattering over the step of `len` voxels from p along d: the distance to
// their first collision in it, or a value >= len for none (`at`: their scattering there).
float field_collision(inout Walk w, vec3 p, vec3 d, float len, float h, out vec4 at) {
    at = vec4(0.0);
    FieldSample start = field_at(p + (0.5 * len) * d);
    float majorant = uintBitsToFloat(start.block.y) * h;  // per voxel
    if (start.block.x == MEDIUM_NO_BRICK || !(majorant > 0.0)) return len;
    float t = 0.0;
    for (int guard = 0; guard < 256; ++guard) {
        t -= log(1.0 - pcg_unit(w.rng)) / majorant;
        if (t >= len) return len;
        at = field_scattering(field_at(p + t * d));
        if (pcg_unit(w.rng) * majorant < (at.r + at.g + at.b) * (1.0 / 3.0) * h) return t;
    }
    return len;
}

// The scattering coefficients (per metre) at coverage c of object o where the medium's density is `density`.
vec3 walk_scattering(float c, uint o, float density) {
    return thinned(scattering_at(c, o), params.medium_scattering.rgb, c, density);
}

// Spends the optical depth of a step of length `len` (voxels of side h) from p along d at coverage c of
// object o, the medium's mean density `density` over the step and the volumes' scattering `field` at its
// midpoint, and returns the coefficient sigma of the photon's continuous absorption (the channels' mean
// scattering, per voxel; 0 once the photon has used its bounces): the photon crosses the whole step, or
// `len` is shortened to where it scatters (w.collides), by the medium's or an object's scattering or, by
// delta tracking, the volumes' (w.by_field). A step lies within one block of the field (field_step).
float walk_free_path(inout Walk w, vec3 p, vec3 d, float c, uint o, float h, float density, vec4 field, inout float len) {
    vec3 s = walk_scattering(c, o, density);
    bool walks = w.bounces < params.models.w;
    float sigma = walks ? (s.r + s.g + s.b) * (1.0 / 3.0) * h : 0.0;  // without the volumes'
    float depth = sigma * len;
    float uniform_at = depth > w.depth_left ? w.depth_left / sigma : len;
    vec4 at = vec4(0.0);
    float field_at_t = kMediumField && walks ? field_collision(w, p, d, len, h, at) : len;
    w.collides = min(uniform_at, field_at_t) < len;
    w.by_field = field_at_t < uniform_at;
    if (w.collides) {
        len = min(uniform_at, field_at_t);
        w.coverage = c;
        w.object = o;
        w.density = density;
        w.field = at;
    }
    // The uniform process spends what it crossed; after a volume's collision it goes on from there.
    if (!w.collides || w.by_field) w.depth_left -= sigma * len;
    float field_sigma = walks && kMediumField ? (field.r + field.g + field.b) * (1.0 / 3.0) * h : 0.0;
    return sigma + field_sigma;
}

// The step (voxels) a walking photon takes from p along d where the octree allows ds, and the coverage
// its coefficients are taken at. The octree splits on n, so where coefficients change and n does not
// (an index-matched object, an imported grid's coverage) a leaf spans the change, and a step across it
// would take its start's coefficients for the whole of it, free path and absorption alike. A step that
// would end at another coverage than it starts at (`coverage`, found by `mode`) is cut to the shell
// step, so the walk crosses the change voxel by voxel, as photons cross a refracting shell; and every
// step takes the mean of its ends' coverage (the trapezoid rule: the start's alone would lag half a
// step behind the change, half a mean free path in a medium as dense as a voxel). (An object thinner
// than a leaf step, entered and left within one, is still stepped over.)
float walk_step(vec3 p, vec3 d, inout float ds, float coverage, uint mode, float shell_step) {
    if (mode == COVERAGE_CONSTANT) return coverage;
    vec3 q = p + d * ds;
    uint cell = field_entry(q);
    float far = coverage_for(mode, q, cell, index_at(q, cell).x);
    if (abs(far - coverage) > 1e-3 && ds > shell_step) {
        ds = shell_step;
        q = p + d * ds;
        cell = field_entry(q);
        far = coverage_for(mode, q, cell, index_at(q, cell).x);
    }
    return 0.5 * (coverage + far);
}

// A unit vector at angle acos(mu) from unit vector d, at azimuth phi about it.
vec3 turn(vec3 d, float mu, float phi) {
    vec3 a = abs(d.x) < 0.9 ? vec3(1.0, 0.0, 0.0) : vec3(0.0, 1.0, 0.0);
    vec3 u = normalize(cross(d, a));
    vec3 v = cross(d, u);
    float sin_theta = sqrt(max(0.0, 1.0 - mu * mu));
    return normalize(mu * d + sin_theta * (cos(phi) * u + sin(phi) * v));
}

// Scatters a photon travelling along d where its step ended at a scattering event: its new direction,
// drawn from the phase function of what scattered it (the volumes' Henyey-Greenstein g, or the region's:
// the object's where the coverage is over 0.5, as the viewing pass gathers), and each channel's weight
// factor sigma_s,c / sigma of that scatterer. `xi`: three uniform numbers, the last for the next free
// path. The walk counts the bounce and starts its next free path.
vec3 scatter(inout Walk w, vec3 d, vec3 xi, out vec3 weight_factor) {
    uint model = phase_model_at(w.coverage, w.object);
    float g = phase_g_at(w.coverage, w.object);
    vec3 s = walk_scattering(w.coverage, w.object, w.density);
    if (kMediumField && w.by_field) {
        float field_mean = (w.field.r + w.field.g + w.field.b) * (1.0 / 3.0);
        model = PHASE_HG_ID;
        g = field_mean > 0.0 ? clamp(w.field.a / field_mean, -0.99, 0.99) : 0.0;
        s = w.field.rgb;
    }
    weight_factor = s * (3.0 / (s.r + s.g + s.b));
    w.bounces += 1u;
    w.depth_left = -log(1.0 - xi.z);
    w.collides = false;
    return turn(d, phase_sample_cos(model, g, xi.x), 6.28318530717959 * xi.y);
}

// Russian roulette after a scattering event: a photon whose weight (relative to the reference flux) has
// fallen below 1/4 goes on with probability 4 x its largest channel and that channel raised to 1/4, else
// it stops with no weight left. Unbiased; walks in weakly absorbing media then end after a few times
// ln(4) / (1 - albedo) bounces instead of running on to the weight floor of 1e-4 (ln(1e4) / (1 - albedo):
// 920 bounces at albedo 0.99).
bool survives_roulette(inout vec3 weight, float xi) {
    float largest = max(weight.r, max(weight.g, weight.b));
    if (largest >= 0.25) return true;
    bool survives = xi * 0.25 < largest;
    weight = survives ? weight * (0.25 / largest) : vec3(0.0);
    return survives;
}
