// The light's emitter, shared by the photon and direct-light passes: where the ray of emission sample
// s in [0,1)^2 starts and goes, and the way back from a point to the sample whose ray passes through it.
// Needs transport_common.glsl (params). The environment's emitter is beside it: emit_environment_ray.
#include "environment.glsl"

// The unit direction of sample s of a cone uniform in solid angle around `axis` (w: the cos of its
// half-angle), u and v across it.
vec3 cone_direction(vec2 s, vec4 axis, vec3 u, vec3 v) {
    float cos_t = 1.0 - s.x * (1.0 - axis.w);
    float sin_t = sqrt(max(0.0, 1.0 - cos_t * cos_t));
    float phi = 6.28318530717959 * s.y;
    return normalize(cos_t * axis.xyz + sin_t * (cos(phi) * u + sin(phi) * v));
}

// Whether a spot lets the ray along `direction` out (a point or directional light lets every ray out).
bool spot_lets_out(vec3 direction) {
    return params.models.z != LIGHT_SPOT ||
           dot(direction, params.light_direction.xyz) >= params.light_position.w;
}

// The ray of emission sample s: world origin and unit direction; false outside a spot's cone.
bool emit_ray(vec2 s, out vec3 origin, out vec3 direction) {
    if (params.models.z == LIGHT_DIRECTIONAL) {
        origin = params.emit_origin.xyz + s.x * params.emit_u.xyz + s.y * params.emit_v.xyz;
        direction = params.emit_axis.xyz;
        return true;
    }
    direction = cone_direction(s, params.emit_axis, params.emit_u.xyz, params.emit_v.xyz);
    origin = params.emit_origin.xyz;
    return spot_lets_out(direction);
}

// The emission sample of the cone ray along unit `direction` (point, spot).
vec2 cone_sample(vec3 direction) {
    float phi = atan(dot(direction, params.emit_v.xyz), dot(direction, params.emit_u.xyz)) * (1.0 / kTwoPi);
    float from_axis = (1.0 - dot(direction, params.emit_axis.xyz)) / (1.0 - params.emit_axis.w);
    return vec2(from_axis, phi < 0.0 ? phi + 1.0 : phi);
}

bool photons_in_part() { return params.photon_part.w > 0.5; }

// Whether the ray of emission sample s along `direction` lies in the photons' part of the emitter.
bool in_photon_part(vec2 s, vec3 direction) {
    if (!photons_in_part()) return true;
    if (params.models.z == LIGHT_DIRECTIONAL)
        return all(greaterThanEqual(s, params.photon_rect.xy)) && all(lessThan(s, params.photon_rect.zw));
    return dot(direction, params.photon_cone.xyz) >= params.photon_cone.w;
}

// The ray of photon sample s in [0,1)^2, uniform over the photons' part of the emitter (in solid angle
// for a cone), and `s_emitter`, its emission sample (the light map's texel); false where no photon goes.
bool emit_photon_ray(vec2 s, out vec3 origin, out vec3 direction, out vec2 s_emitter) {
    if (!photons_in_part()) {
        s_emitter = s;
        return emit_ray(s, origin, direction);
    }
    if (params.models.z == LIGHT_DIRECTIONAL) {
        s_emitter = mix(params.photon_rect.xy, params.photon_rect.zw, s);
        return emit_ray(s_emitter, origin, direction);
    }
    vec3 u = params.photon_part.xyz;
    direction = cone_direction(s, params.photon_cone, u, cross(params.photon_cone.xyz, u));
    origin = params.emit_origin.xyz;
    s_emitter = cone_sample(direction);
    return s_emitter.x < 1.0 && spot_lets_out(direction);
}

// Photon samples per emission sample, over the photons' part: the inverse of its share of the emitter.
float photon_samples_per_emission_sample() {
    if (!photons_in_part()) return 1.0;
    if (params.models.z == LIGHT_DIRECTIONAL) {
        vec2 side = params.photon_rect.zw - params.photon_rect.xy;
        return 1.0 / (side.x * side.y);
    }
    return (1.0 - params.emit_axis.w) / (1.0 - params.photon_cone.w);
}

// The first of `count` CDF values (inclusive, ascending) at map.texels[first + k * stride] above s, and
// where s lies between it and the one before (0..1): what is left of s to draw the next choice with.
uint draw_from_cdf(EnvironmentTexels map, uint first, uint stride, uint count, uint component, float s, out float rest) {
    uint lo = 0u, hi = count - 1u;
    while (lo < hi) {
        uint mid = (lo + hi) / 2u;
        if (map.texels[first + mid * stride][component] > s) hi = mid;
        else lo = mid + 1u;
    }
    float before = lo > 0u ? map.texels[first + (lo - 1u) * stride][component] : 0.0;
    float after = map.texels[first + lo * stride][component];
    rest = clamp((s - before) / max(after - before, 1e-30), 0.0, 0.99999994);
    return lo;
}

// The ray of an environment photon: s.x draws the map's row and, with what is left of it, the polar angle
// uniformly in cos theta within the row's sampled part; s.y the column and the azimuth within it (so the
// direction's pdf is the pixel's probability over its solid angle, constant within the pixel). It
// travels away from that direction, from a point drawn uniformly (disc in [0,1)^2) on the disc that faces
// it across the grid's bounding sphere. weight: its flux relative to photon_flux.w.
void emit_environment_ray(vec2 s, vec2 disc, out vec3 origin, out vec3 direction, out vec3 weight) {
    EnvironmentTexels map = EnvironmentTexels(params.environment_map.xy);
    uint width = params.environment.x, height = params.environment.y;
    uint rows = ENVIRONMENT_ROWS_AT(width, height);
    float rest_v, rest_u;
    uint v = draw_from_cdf(map, rows, 1u, height, 0u, s.x, rest_v);
    vec4 row = map.texels[rows + v];
    uint u = draw_from_cdf(map, v * width, 1u, width, 3u, s.y, rest_u);
    vec4 texel = map.texels[v * width + u];
    float cos_theta = mix(row.y, row.z, rest_v);
    float sin_theta = sqrt(max(0.0, 1.0 - cos_theta * cos_theta));
    float phi = kTwoPi * (float(u) + rest_u) / float(width);
    vec3 toward = turn_environment(vec3(sin_theta * cos(phi), cos_theta, sin_theta * sin(phi)), false);
    direction = -toward;
    vec3 across = normalize(abs(toward.x) < 0.9 ? cross(toward, vec3(1.0, 0.0, 0.0)) : cross(toward, vec3(0.0, 1.0, 0.0)));
    vec3 across2 = cross(toward, across);
    float radius = params.environment_frame.z;
    float r = radius * sqrt(disc.x), angle = kTwoPi * disc.y;
    vec3 centre = params.grid_origin.xyz + 0.5 * vec3(params.grid_dims.xyz) * params.grid_origin.w;
    origin = centre + toward * (1.01 * radius) + r * (cos(angle) * across + sin(angle) * across2);
    weight = texel.rgb * (3.0 * params.environment_frame.w / max(texel.r + texel.g + texel.b, 1e-30));
}

layout(buffer_reference, std430, buffer_reference_align = 8) readonly buffer MediumEmitters { uvec2 entries[]; };

// The ray of a photon the volumes emit (transport.h, volume_emission): `pick` draws its field voxel from
// the emitters' table by what each emits, `within` the point in that voxel, `turn` its direction,
// uniform on the sphere. Origin in world units. weight: its flux relative to photon_flux.w, the voxel's
// colour over the colour's mean times volume_emission_flux.x.
void emit_volume_ray(float pick, vec3 within, vec2 turn, out vec3 origin, out vec3 direction, out vec3 weight) {
    MediumEmitters table = MediumEmitters(params.volume_emission.zw);
    uint lo = 0u, hi = params.volume_emission.y - 1u;
    while (lo < hi) {
        uint mid = (lo + hi) / 2u;
        if (uintBitsToFloat(table.entries[mid].y) > pick) hi = mid;
        else lo = mid + 1u;
    }
    uint voxel = table.entries[lo].x, mask = (1u << MEDIUM_VOXEL_BITS) - 1u;
    vec3 v = vec3(uvec3(voxel & mask, (voxel >> MEDIUM_VOXEL_BITS) & mask, voxel >> (2u * MEDIUM_VOXEL_BITS)));
    vec3 colour = field_emission(field_at((v + 0.5) * params.medium_field.w));  // the voxel's own value, at its centre
    origin = to_world((v + within) * params.medium_field.w);
    float cos_t = 1.0 - 2.0 * turn.x, sin_t = sqrt(max(0.0, 1.0 - cos_t * cos_t));
    float phi = kTwoPi * turn.y;
    direction = vec3(sin_t * cos(phi), sin_t * sin(phi), cos_t);
    weight = colour * (3.0 * params.volume_emission_flux.x / max(colour.r + colour.g + colour.b, 1e-30));
}

// The unit direction of the light's ray through world point x, and how far x lies along it (voxels,
// from the light or the emitter's plane).
vec3 ray_through(vec3 x, out float along) {
    vec3 rel = x - params.emit_origin.xyz;
    if (params.models.z == LIGHT_DIRECTIONAL) {
        along = dot(rel, params.emit_axis.xyz) / params.grid_origin.w;
        return params.emit_axis.xyz;
    }
    float r = length(rel);
    along = r / params.grid_origin.w;
    return rel / r;
}

// The emission sample whose ray passes through world point x, with ray_through's values; false where no
// photon goes (outside the emitter or a spot's cone).
bool emission_sample(vec3 x, out vec2 s, out float along, out vec3 direction) {
    direction = ray_through(x, along);
    if (params.models.z == LIGHT_DIRECTIONAL) {
        vec3 rel = x - params.emit_origin.xyz;
        s = vec2(dot(rel, params.emit_u.xyz) / dot(params.emit_u.xyz, params.emit_u.xyz),
                 dot(rel, params.emit_v.xyz) / dot(params.emit_v.xyz, params.emit_v.xyz));
        return all(greaterThanEqual(s, vec2(0.0))) && all(lessThan(s, vec2(1.0)));
    }
    s = cone_sample(direction);
    return s.x < 1.0 && spot_lets_out(direction);
}

// What the medium lets through of the light's straight ray to world point x (medium_transmittance).
vec3 straight_transmittance(vec3 x) {
    float along;
    vec3 d = ray_through(x, along);
    return medium_transmittance(x, -d, params.models.z == LIGHT_DIRECTIONAL ? 1e30 : along * voxel_size());
}

// Whether light at a field sample (n, grad n) with this coverage goes on straight through the medium,
// as direct light assumes (DIRECT_FLAT).
bool flat_medium(vec4 field, float coverage) {
    return all(lessThanEqual(abs(field.yzw), vec3(DIRECT_FLAT))) && coverage <= DIRECT_FLAT;
}

// The light-map texel of emission sample s.
uint light_map_texel(vec2 s) {
    uint side = uint(params.direct_light.x);
    uvec2 t = min(uvec2(s * float(side)), uvec2(side - 1u));
    return t.y * side + t.x;
}
