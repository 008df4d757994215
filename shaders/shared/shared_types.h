// Lets the shared shader headers compile as GLSL and as C++ (glm types, namespace refract::shaders).
#ifndef REFRACT_SHADERS_SHARED_TYPES_H
#define REFRACT_SHADERS_SHARED_TYPES_H

#ifdef __cplusplus
#include <cstdint>
#include <glm/glm.hpp>
#define REFRACT_SHADERS_BEGIN namespace refract::shaders { using namespace glm; using uint = uint32_t;
#define REFRACT_SHADERS_END }
#define REFRACT_INLINE inline
#else
#define REFRACT_SHADERS_BEGIN
#define REFRACT_SHADERS_END
#define REFRACT_INLINE
#endif

#endif
