// The light's emitter, shared by the photon and direct-light passes: where the ray of emission sample
// s in [0,1)^2 starts and goes, and the way back from a point to the sample whose ray passes through it.
// Needs transport_common.glsl (params).

// The ray of emission sample s: world origin and unit direction; false outside a spot's cone.
bool emit_ray(vec2 s, out vec3 origin, out vec3 direction) {
    if (params.models.z == LIGHT_DIRECTIONAL) {
        origin = params.emit_origin.xyz + s.x * params.emit_u.xyz + s.y * params.emit_v.xyz;
        direction = params.emit_axis.xyz;
        return true;
    }
    // Uniform in solid angle over the cone around emit_axis.
    float cos_t = 1.0 - s.x * (1.0 - params.emit_axis.w);
    float sin_t = sqrt(max(0.0, 1.0 - cos_t * cos_t));
    float phi = 6.28318530717959 * s.y;
    direction = normalize(cos_t * params.emit_axis.xyz + sin_t * (cos(phi) * params.emit_u.xyz + sin(phi) * params.emit_v.xyz));
    origin = params.emit_origin.xyz;
    return params.models.z != LIGHT_SPOT || dot(direction, params.light_direction.xyz) >= params.light_position.w;
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
    float phi = atan(dot(direction, params.emit_v.xyz), dot(direction, params.emit_u.xyz)) * (1.0 / 6.28318530717959);
    s = vec2((1.0 - dot(direction, params.emit_axis.xyz)) / (1.0 - params.emit_axis.w), phi < 0.0 ? phi + 1.0 : phi);
    return s.x < 1.0 &&
           (params.models.z != LIGHT_SPOT || dot(direction, params.light_direction.xyz) >= params.light_position.w);
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
