// VkResult checking: every Vulkan call goes through REFRACT_VK_CHECK, which throws vk::Error naming the
// call, the file and the line. Library code never exits or aborts.
#pragma once

#include <stdexcept>
#include <string>

#include <vulkan/vulkan.h>

namespace refract::vk {

class Error : public std::runtime_error {
public:
    Error(const std::string& what, VkResult result = VK_SUCCESS) : std::runtime_error(what), result_(result) {}
    VkResult result() const { return result_; }

private:
    VkResult result_;
};

// A request beyond what this device can do or hold (a buffer past its storage binding range, an image past
// its dimension limit, a dispatch past its workgroup count): the request's fault, not the device's.
class LimitError : public Error {
public:
    using Error::Error;
};

const char* result_name(VkResult result);

void throw_result(VkResult result, const char* expression, const char* file, int line);

inline void check(VkResult result, const char* expression, const char* file, int line) {
    if (result != VK_SUCCESS) throw_result(result, expression, file, line);
}

}  // namespace refract::vk

#define REFRACT_VK_CHECK(expr) ::refract::vk::check((expr), #expr, __FILE__, __LINE__)
