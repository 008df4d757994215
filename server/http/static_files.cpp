#include "http/static_files.h"

#include <algorithm>
#include <cctype>
#include <map>

namespace refract::http {

namespace fs = std::filesystem;

std::string content_type_for(const fs::path& path) {
    static const std::map<std::string, std::string> types = {
        {".html", "text/html; charset=utf-8"},
        {".htm", "text/html; charset=utf-8"},
        {".js", "text/javascript; charset=utf-8"},
        {".mjs", "text/javascript; charset=utf-8"},
        {".css", "text/css; charset=utf-8"},
        {".json", "application/json"},
        {".png", "image/png"},
        {".svg", "image/svg+xml"},
        {".ico", "image/x-icon"},
        {".jpg", "image/jpeg"},
        {".jpeg", "image/jpeg"},
        {".txt", "text/plain; charset=utf-8"},
        {".wasm", "application/wasm"},
        {".obj", "text/plain; charset=utf-8"},
        {".map", "application/json"},
    };
    std::string ext = path.extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    auto it = types.find(ext);
    return it == types.end() ? "application/octet-stream" : it->second;
}

StaticFile resolve_static(const fs::path& web_root, const std::string& url_path) {
    StaticFile result;
    if (url_path.empty() || url_path.front() != '/' || url_path.find('\0') != std::string::npos ||
        url_path.find('\\') != std::string::npos) {
        result.status = 400;
        return result;
    }
    // Refuse any ".." segment outright, before touching the file system.
    size_t start = 1;
    while (start <= url_path.size()) {
        size_t end = url_path.find('/', start);
        if (end == std::string::npos) end = url_path.size();
        if (url_path.compare(start, end - start, "..") == 0 && end - start == 2) {
            result.status = 400;
            return result;
        }
        start = end + 1;
    }

    std::error_code ec;
    fs::path root = fs::canonical(web_root, ec);
    if (ec) return result;
    fs::path candidate = root / fs::path(url_path.substr(1));
    if (fs::is_directory(candidate, ec)) candidate /= "index.html";
    fs::path resolved = fs::weakly_canonical(candidate, ec);
    if (ec) return result;
    // Symlinks are resolved above: whatever the path names must still lie inside the root.
    auto [root_end, resolved_it] = std::mismatch(root.begin(), root.end(), resolved.begin(), resolved.end());
    if (root_end != root.end() || resolved == root) {
        result.status = 404;
        return result;
    }
    if (!fs::is_regular_file(resolved, ec)) return result;
    result.status = 200;
    result.path = resolved;
    result.content_type = content_type_for(resolved);
    return result;
}

}  // namespace refract::http
