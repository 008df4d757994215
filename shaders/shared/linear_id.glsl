// Include after the shader's local_size layout: before it, glslang takes gl_WorkGroupSize as 1.
// 1D work larger than one dispatch dimension allows (65535 groups) is dispatched as a 2D grid of
// groups; this recovers the linear item index (see vk::linear_groups on the host).
uint linear_invocation() {
    return gl_GlobalInvocationID.y * (gl_NumWorkGroups.x * gl_WorkGroupSize.x) + gl_GlobalInvocationID.x;
}
