// The environment map (transport.h, ENVIRONMENT_ROWS_AT), reached by device address: what rays that
// leave the scene see, and where environment photons come from. Needs transport_common.glsl (params).
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_buffer_reference_uvec2 : require
layout(buffer_reference, std430, buffer_reference_align = 16) readonly buffer EnvironmentTexels { vec4 texels[]; };

const float kTwoPi = 6.28318530717959;

// A direction of the map turned by the environment's rotation about +y into the world's, and back
// (inverse = true).
vec3 turn_environment(vec3 d, bool inverse) {
    float c = params.environment_frame.x, s = inverse ? -params.environment_frame.y : params.environment_frame.y;
    return vec3(d.x * c - d.z * s, d.y, d.z * c + d.x * s);
}

// The radiance the map holds towards world direction d (nearest texel).
vec3 environment_radiance(vec3 d) {
    EnvironmentTexels map = EnvironmentTexels(params.environment_map.xy);
    uint width = params.environment.x, height = params.environment.y;
    vec3 m = turn_environment(d, true);
    float theta = acos(clamp(m.y, -1.0, 1.0));
    float phi = atan(m.z, m.x);
    phi = phi < 0.0 ? phi + kTwoPi : phi;
    uint u = min(uint(phi * (float(width) / kTwoPi)), width - 1u);
    uint v = min(uint(theta * (float(height) / 3.14159265358979)), height - 1u);
    return map.texels[v * width + u].rgb;
}
