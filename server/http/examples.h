// Example scenes: the examples/*.json documents served to clients at /api/examples, looked up by name.
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>
#include <vector>

namespace refract::http {

// Whether `name` may name an example: 1 to 64 characters from [a-z0-9_] (no dots, slashes or "..").
bool valid_example_name(std::string_view name);

// The names of the examples in `dir` (its NAME.json files with valid names), sorted; empty when `dir`
// does not exist or cannot be read.
std::vector<std::string> list_examples(const std::filesystem::path& dir);

// The title shown for an example, from its name: "ball_lens_fog" -> "Ball lens fog". (A scene document
// has no room for a title: unknown top-level fields are rejected.)
std::string example_title(std::string_view name);

// `{"examples": [{"name", "title"}]}` for the examples in `dir`.
nlohmann::json examples_index(const std::filesystem::path& dir);

// An example looked up by name: its document (status 200), or why not: 400 a name that is not valid,
// 404 no such example (or a file that resolves outside `dir`), 500 a file that is not JSON.
struct ExampleFile {
    int status = 404;
    nlohmann::json document;
    std::string error;
};

// Reads example `name` from `dir`; never reads anything but `dir`/NAME.json.
ExampleFile read_example(const std::filesystem::path& dir, std::string_view name);

}  // namespace refract::http
