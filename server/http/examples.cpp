#include "http/examples.h"

#include <algorithm>
#include <fstream>
#include <optional>
#include <sstream>

namespace refract::http {

namespace fs = std::filesystem;

namespace {

constexpr size_t kMaxName = 64;
constexpr std::string_view kExtension = ".json";

// `dir`/NAME.json when it is a regular file that still lies in `dir` once symlinks are resolved.
std::optional<fs::path> example_path(const fs::path& dir, std::string_view name) {
    std::error_code ec;
    fs::path root = fs::canonical(dir, ec);
    if (ec) return std::nullopt;
    fs::path file = fs::canonical(root / (std::string(name) + std::string(kExtension)), ec);
    if (ec || file.parent_path() != root || !fs::is_regular_file(file, ec)) return std::nullopt;
    return file;
}

}  // namespace

bool valid_example_name(std::string_view name) {
    return !name.empty() && name.size() <= kMaxName && std::all_of(name.begin(), name.end(), [](char c) {
        return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_';
    });
}

std::vector<std::string> list_examples(const fs::path& dir) {
    std::vector<std::string> names;
    std::error_code ec;
    for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
        const fs::path& file = it->path();
        if (file.extension() != kExtension) continue;
        std::string name = file.stem().string();
        if (valid_example_name(name) && example_path(dir, name)) names.push_back(std::move(name));
    }
    std::sort(names.begin(), names.end());
    return names;
}

std::string example_title(std::string_view name) {
    std::string title(name);
    std::replace(title.begin(), title.end(), '_', ' ');
    if (!title.empty() && title[0] >= 'a' && title[0] <= 'z') title[0] = static_cast<char>(title[0] - 'a' + 'A');
    return title;
}

nlohmann::json examples_index(const fs::path& dir) {
    nlohmann::json list = nlohmann::json::array();
    for (const std::string& name : list_examples(dir)) list.push_back({{"name", name}, {"title", example_title(name)}});
    return {{"examples", list}};
}

ExampleFile read_example(const fs::path& dir, std::string_view name) {
    ExampleFile result;
    if (!valid_example_name(name)) {
        result.status = 400;
        result.error = "an example name is 1 to 64 characters from a-z, 0-9 and _";
        return result;
    }
    std::optional<fs::path> file = example_path(dir, name);
    std::ifstream in;
    if (file) in.open(*file, std::ios::binary);
    if (!file || !in.is_open()) {
        result.error = "no example named '" + std::string(name) + "'";
        return result;
    }
    std::ostringstream text;
    text << in.rdbuf();
    result.document = nlohmann::json::parse(text.str(), nullptr, false);
    if (result.document.is_discarded() || !result.document.is_object()) {
        result.status = 500;
        result.document = nullptr;
        result.error = "example '" + std::string(name) + "' is not a JSON object";
        return result;
    }
    result.status = 200;
    return result;
}

}  // namespace refract::http
