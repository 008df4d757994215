#include "vk/check.h"

#include <sstream>

namespace refract::vk {

const char* result_name(VkResult result) {
    switch (result) {
#define REFRACT_RESULT_CASE(r) \
    case r:                    \
        return #r;
        REFRACT_RESULT_CASE(VK_SUCCESS)
        REFRACT_RESULT_CASE(VK_NOT_READY)
        REFRACT_RESULT_CASE(VK_TIMEOUT)
        REFRACT_RESULT_CASE(VK_INCOMPLETE)
        REFRACT_RESULT_CASE(VK_ERROR_OUT_OF_HOST_MEMORY)
        REFRACT_RESULT_CASE(VK_ERROR_OUT_OF_DEVICE_MEMORY)
        REFRACT_RESULT_CASE(VK_ERROR_INITIALIZATION_FAILED)
        REFRACT_RESULT_CASE(VK_ERROR_DEVICE_LOST)
        REFRACT_RESULT_CASE(VK_ERROR_MEMORY_MAP_FAILED)
        REFRACT_RESULT_CASE(VK_ERROR_LAYER_NOT_PRESENT)
        REFRACT_RESULT_CASE(VK_ERROR_EXTENSION_NOT_PRESENT)
        REFRACT_RESULT_CASE(VK_ERROR_FEATURE_NOT_PRESENT)
        REFRACT_RESULT_CASE(VK_ERROR_INCOMPATIBLE_DRIVER)
        REFRACT_RESULT_CASE(VK_ERROR_TOO_MANY_OBJECTS)
        REFRACT_RESULT_CASE(VK_ERROR_FORMAT_NOT_SUPPORTED)
        REFRACT_RESULT_CASE(VK_ERROR_FRAGMENTED_POOL)
        REFRACT_RESULT_CASE(VK_ERROR_OUT_OF_POOL_MEMORY)
        REFRACT_RESULT_CASE(VK_ERROR_UNKNOWN)
#undef REFRACT_RESULT_CASE
        default:
            return "VkResult(unknown)";
    }
}

void throw_result(VkResult result, const char* expression, const char* file, int line) {
    std::ostringstream message;
    message << expression << " failed with " << result_name(result) << " (" << static_cast<int>(result)
            << ") at " << file << ":" << line;
    throw Error(message.str(), result);
}

}  // namespace refract::vk
