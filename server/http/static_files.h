// Static files of the web client, served at / without ever leaving the web root.
#pragma once

#include <filesystem>
#include <string>

namespace refract::http {

// What a request path resolves to: a readable file under the root (status 200) or why not (400, 404).
struct StaticFile {
    int status = 404;
    std::filesystem::path path;
    std::string content_type;
};

// Resolves a decoded URL path ("/", "/js/app.js") under `web_root`: "/" and directories mean their
// index.html; any ".." segment, NUL byte or symlink leading outside the root is refused.
StaticFile resolve_static(const std::filesystem::path& web_root, const std::string& url_path);

// The Content-Type for a file name's extension (html, js, css, png, svg, json, ...).
std::string content_type_for(const std::filesystem::path& path);

}  // namespace refract::http
