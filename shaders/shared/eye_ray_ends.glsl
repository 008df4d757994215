// Where an eye ray ends: the floor (lit analytically, plus the photons' floor map of what the grid
// changes there: its shadow and caustics) or the sky. Shared by the viewing pass and view_upscale.comp,
// which evaluates the ends of straight eye rays at the viewer's size. Needs transport_common.glsl,
// environment.glsl and the including pass's `floor_map` (TRANSPORT_BINDING_FLOOR_MAP). A pass that knows
// its frames have one light defines EYE_RAY_ENDS_ONE_LIGHT and a constant kOneLight before including it.
#ifndef EYE_RAY_ENDS_ONE_LIGHT
const bool kOneLight = false;
#endif

const float kPi = 3.14159265358979;

// How far along d from p (voxels) the floor's plane lies; 1e30 where there is no floor or d does not
// descend.
float to_floor_plane(vec3 p, vec3 d) {
    return (floor_enabled() && d.y < 0.0) ? (p.y - floor_height_voxels()) / -d.y : 1e30;
}

// Irradiance straight from every light at a floor point (normal +y), through the medium but past no
// object (medium_transmittance), over a pixel's footprint there, the box with edges `along` and `across`
// (metres, on the floor): a spot's cone edge is box-filtered across it (the share of the footprint inside
// the cone, by the angle off the spot's axis, which changes across the box by the box's extent along that
// angle's gradient), so the lit disc's rim is not stair-stepped.
vec3 direct_irradiance(vec3 x, vec3 along, vec3 across) {
    vec3 irradiance = vec3(0.0);
    for (uint k = 0u; k < (kOneLight ? 1u : params.light_set.x); ++k) {
        // From the buffer, not load_params()'s private copy: indexed by k there, the whole light array
        // is copied per invocation (view_upscale.comp: 17.5 -> 14.9 ms at 768 x 482 on two cores). By k
        // lavapipe loads it lane by lane inside the loop, by a constant index once (16.2-17.4 -> 14.1-14.4).
        LightParams light = frame_params.lights[kOneLight ? 0u : k];
        if (light.type.x == LIGHT_DIRECTIONAL) {
            irradiance += light.power.rgb * max(0.0, -light.direction.y) *
                          medium_transmittance(x, -light.direction.xyz, 1e30);
            continue;
        }
        vec3 l = light.position.xyz - x;
        float r2 = dot(l, l);
        vec3 to_light = l / sqrt(r2);
        float inside = 1.0;
        if (light.type.x == LIGHT_SPOT) {
            float cos_off = clamp(dot(-to_light, light.direction.xyz), -1.0, 1.0);
            float off_axis = acos(cos_off);
            float rim = acos(clamp(light.position.w, -1.0, 1.0));
            // The gradient of the off-axis angle at x: away from the axis, of size 1 / r.
            vec3 away = cos_off * -to_light - light.direction.xyz;
            vec3 gradient = away / max(length(away) * sqrt(r2), 1e-12);
            float width = abs(dot(gradient, along)) + abs(dot(gradient, across));
            inside = width > 1e-6 ? clamp((rim - off_axis) / width + 0.5, 0.0, 1.0) : (off_axis <= rim ? 1.0 : 0.0);
        }
        irradiance += inside * light.power.rgb * max(0.0, to_light.y) / r2 *
                      medium_transmittance(x, to_light, sqrt(r2));
    }
    return irradiance;
}

// The checker's square wave along one axis (+1 on even cells, -1 on odd ones, u in cells), averaged over
// [u - w / 2, u + w / 2]: differences of its integral, a triangle wave. The box filter of the pixel's
// footprint, exactly, so the checker does not alias into moire toward the horizon (TEMPORAL.md).
float checker_integral(float u) { return 1.0 - abs(mod(u, 2.0) - 1.0); }
float filtered_square(float u, float w) {
    if (w < 1e-3) return mod(floor(u), 2.0) == 0.0 ? 1.0 : -1.0;
    return (checker_integral(u + 0.5 * w) - checker_integral(u - 0.5 * w)) / w;
}

// The floor map at m (0 to 1 across it), interpolated bilinearly between its texels' centres and held at
// its edge, as a linear sampler clamped to the edge reads an image.
vec3 floor_map_at(vec2 m) {
    int side = int(params.floor_map.w);
    vec2 t = m * float(side) - 0.5;
    vec2 low = floor(t), f = t - low;
    ivec2 lo = clamp(ivec2(low), ivec2(0), ivec2(side - 1));
    ivec2 hi = clamp(ivec2(low) + 1, ivec2(0), ivec2(side - 1));
    vec3 a = floor_map_texel(floor_map[lo.y * side + lo.x]).rgb;
    vec3 b = floor_map_texel(floor_map[lo.y * side + hi.x]).rgb;
    vec3 c = floor_map_texel(floor_map[hi.y * side + lo.x]).rgb;
    vec3 d = floor_map_texel(floor_map[hi.y * side + hi.x]).rgb;
    return mix(mix(a, b, f.x), mix(c, d, f.x), f.y);
}

// The floor's radiance at x over a pixel's footprint there: the box with edges `along` and `across`
// (metres on the floor, conjugate half-axes of the footprint's ellipse), the checker filtered over the
// box around that ellipse, `checker_width` (its extent along the floor's x and z, in cells).
vec3 floor_radiance_over(vec3 x, vec3 along, vec3 across, vec2 checker_width) {
    // Unobstructed light plus what the grid changed (shadow, caustics; see photon_trace.comp).
    vec2 m = (x.xz - params.floor_map.xy) / params.floor_map.z;
    vec3 irradiance = direct_irradiance(x, along, across) + params.environment_light.rgb;
    if (all(greaterThanEqual(m, vec2(0.0))) && all(lessThanEqual(m, vec2(1.0))))
        irradiance = max(irradiance + floor_map_at(m), vec3(0.0));
    vec3 albedo = params.floor_albedo.rgb;
    if (params.floor_plane.w > 0.5) {
        vec2 c = x.xz / params.floor_plane.y;
        float dark = 0.5 - 0.5 * filtered_square(c.x, checker_width.x) * filtered_square(c.y, checker_width.y);
        albedo *= mix(1.0, 0.35, dark);
    }
    return albedo * (1.0 / kPi) * irradiance;
}

// A pixel's footprint on the floor for an eye ray arriving along d that has come `distance` (metres)
// straight from the eye, of an image `image_height` pixels tall: its cone's width, stretched along the
// ray's horizontal direction by 1 / |d.y|; the checker's width over the box around that ellipse.
void cone_footprint(vec3 d, float distance, float image_height, out vec3 along, out vec3 across, out vec2 checker_width) {
    float a = distance * 2.0 * params.camera_position.w / image_height;  // metres
    float l = a / max(abs(d.y), 1e-3);  // stretched along the ray's horizontal direction
    vec2 u = length(d.xz) > 1e-6 ? normalize(d.xz) : vec2(1.0, 0.0);
    checker_width = sqrt(l * l * u * u + a * a * u.yx * u.yx) / params.floor_plane.y;
    along = l * vec3(u.x, 0.0, u.y);
    across = a * vec3(-u.y, 0.0, u.x);
}

// The floor's radiance at x for an eye ray arriving along d straight from the eye (cone_footprint).
vec3 floor_radiance(vec3 x, vec3 d, float distance, float image_height) {
    vec3 along, across;
    vec2 w;
    cone_footprint(d, distance, image_height, along, across, w);
    return floor_radiance_over(x, along, across, w);
}

// What a ray leaving the scene along d sees: the image environment's map, else the sky's gradient (one
// colour for a uniform environment).
vec3 sky(vec3 d) {
    if (params.environment.w == 1u) return environment_radiance(d);
    return mix(params.sky_horizon.rgb, params.sky_zenith.rgb, clamp(d.y, 0.0, 1.0));
}

// Where point `at` of a width x height image (pixels; a pixel's centre is its index + 0.5) lies on the
// camera's image plane at distance 1, and the eye ray through it: the viewing pass's rays and the
// upscale's are the same rays.
vec2 image_plane_point(vec2 at, uint width, uint height) {
    float aspect = float(width) / float(height);
    return vec2((2.0 * at.x / float(width) - 1.0) * aspect, 1.0 - 2.0 * at.y / float(height)) * params.camera_position.w;
}
vec3 eye_direction(vec2 ndc) {
    return normalize(params.camera_forward.xyz + ndc.x * params.camera_right.xyz + ndc.y * params.camera_up.xyz);
}
