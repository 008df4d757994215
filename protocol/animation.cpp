#include "protocol/animation.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

namespace refract::protocol {
namespace {

using nlohmann::json;

// A unit quaternion (w, x, y, z).
struct Quat {
    double w, x, y, z;
};

Quat multiply(const Quat& a, const Quat& b) {
    return {a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z, a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y,
            a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x, a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w};
}

constexpr double kRadians = std::numbers::pi / 180.0;

// The object's rotation (degrees, applied X then Y then Z, as mesh::transformed does: R = Rz Ry Rx).
Quat from_euler(const Vec3& deg) {
    const double hx = 0.5 * deg[0] * kRadians, hy = 0.5 * deg[1] * kRadians, hz = 0.5 * deg[2] * kRadians;
    const Quat qx{std::cos(hx), std::sin(hx), 0.0, 0.0}, qy{std::cos(hy), 0.0, std::sin(hy), 0.0},
        qz{std::cos(hz), 0.0, 0.0, std::sin(hz)};
    return multiply(qz, multiply(qy, qx));
}

// The XYZ angles of R = Rz(c) Ry(b) Rx(a): R20 = -sin b, R21 = cos b sin a, R22 = cos b cos a,
// R10 = cos b sin c, R00 = cos b cos c.
Vec3 to_euler(const Quat& q) {
    const double r00 = 1.0 - 2.0 * (q.y * q.y + q.z * q.z), r10 = 2.0 * (q.x * q.y + q.w * q.z);
    const double r20 = 2.0 * (q.x * q.z - q.w * q.y), r21 = 2.0 * (q.y * q.z + q.w * q.x);
    const double r22 = 1.0 - 2.0 * (q.x * q.x + q.y * q.y);
    return {std::atan2(r21, r22) / kRadians, std::asin(std::clamp(-r20, -1.0, 1.0)) / kRadians,
            std::atan2(r10, r00) / kRadians};
}

// Spherical interpolation of unit 4-vectors (or 3-vectors with a zero last component) along the
// shorter arc when `shortest`.
std::array<double, 4> slerp(std::array<double, 4> a, std::array<double, 4> b, double u, bool shortest) {
    double dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3];
    if (shortest && dot < 0.0) {
        for (double& v : b) v = -v;
        dot = -dot;
    }
    std::array<double, 4> r{};
    if (dot > 0.9995) {  // nearly equal: the chord is the arc
        for (size_t i = 0; i < 4; ++i) r[i] = a[i] + u * (b[i] - a[i]);
    } else {
        const double angle = std::acos(std::clamp(dot, -1.0, 1.0));
        const double wa = std::sin((1.0 - u) * angle) / std::sin(angle), wb = std::sin(u * angle) / std::sin(angle);
        for (size_t i = 0; i < 4; ++i) r[i] = wa * a[i] + wb * b[i];
    }
    const double len = std::sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2] + r[3] * r[3]);
    for (double& v : r) v /= len;
    return r;
}

Vec3 vec3_of(const json& j) { return {j[0].get<double>(), j[1].get<double>(), j[2].get<double>()}; }
bool is_vec3(const json& j) {
    return j.is_array() && j.size() == 3 && std::all_of(j.begin(), j.end(), [](const json& v) { return v.is_number(); });
}

json rotation_between(const json& a, const json& b, double u) {
    const Vec3 ra = vec3_of(a), rb = vec3_of(b);
    int changed = 0;
    for (size_t i = 0; i < 3; ++i) changed += ra[i] != rb[i] ? 1 : 0;
    if (changed <= 1) return {ra[0] + u * (rb[0] - ra[0]), ra[1] + u * (rb[1] - ra[1]), ra[2] + u * (rb[2] - ra[2])};
    const Quat qa = from_euler(ra), qb = from_euler(rb);
    const auto q = slerp({qa.w, qa.x, qa.y, qa.z}, {qb.w, qb.x, qb.y, qb.z}, u, true);
    const Vec3 e = to_euler({q[0], q[1], q[2], q[3]});
    return {e[0], e[1], e[2]};
}

json direction_between(const json& a, const json& b, double u) {
    Vec3 da = vec3_of(a), db = vec3_of(b);
    const double la = std::hypot(da[0], da[1], da[2]), lb = std::hypot(db[0], db[1], db[2]);
    const double dot = (da[0] * db[0] + da[1] * db[1] + da[2] * db[2]) / (la * lb);
    if (la == 0.0 || lb == 0.0 || dot < -0.9999)  // no arc is the one meant: move straight
        return {da[0] + u * (db[0] - da[0]), da[1] + u * (db[1] - da[1]), da[2] + u * (db[2] - da[2])};
    const auto d = slerp({da[0] / la, da[1] / la, da[2] / la, 0.0}, {db[0] / lb, db[1] / lb, db[2] / lb, 0.0}, u, false);
    return {d[0], d[1], d[2]};
}

// Document a at u = 0 to document b at u = 1 (both to_json forms of valid documents).
json between(const json& a, const json& b, double u, const std::string& key) {
    if (a == b) return a;  // what the keyframes leave alone stays exactly as it is
    if (a.is_object() && b.is_object()) {
        json out = json::object();
        for (const auto& [k, v] : a.items()) out[k] = b.contains(k) ? between(v, b[k], u, k) : v;
        return out;
    }
    if (key == "rotation_deg" && is_vec3(a) && is_vec3(b)) return rotation_between(a, b, u);
    if (key == "direction" && is_vec3(a) && is_vec3(b)) return direction_between(a, b, u);
    if (a.is_array() && b.is_array() && a.size() == b.size()) {
        json out = json::array();
        for (size_t i = 0; i < a.size(); ++i) out.push_back(between(a[i], b[i], u, key));
        return out;
    }
    if (a.is_number_float() && b.is_number_float()) return a.get<double>() + u * (b.get<double>() - a.get<double>());
    return a;
}

// The JSON pointer of keyframe i's field (appended: GCC 12 warns falsely on "/" + std::string).
std::string pointer(size_t i, const std::string& field = {}) {
    std::string p = "/";
    p += std::to_string(i);
    if (!field.empty()) {
        p += '/';
        p += field;
    }
    return p;
}

}  // namespace

namespace {
// A keyframe's document from the one before it; an empty patch leaves it as it is (and costs nothing).
SceneDocument patched(const SceneDocument& before, const json& patch, const Limits& limits) {
    return patch.empty() ? before : apply_merge_patch(before, patch, limits);
}
}  // namespace

Animation::Animation(const SceneDocument& base, const json& keyframes, const Limits& limits,
                     const std::function<bool()>& keep_going)
    : limits_(limits) {
    if (!keyframes.is_array()) throw ValidationError("", "keyframes must be a list of {\"time\", \"patch\"}");
    if (keyframes.empty()) throw ValidationError("", "keyframes must not be empty");
    if (keyframes.size() > kMaxKeyframes)
        throw ValidationError("", "at most " + std::to_string(kMaxKeyframes) + " keyframes");
    stride_ = (keyframes.size() + kMaxCheckpoints - 1) / kMaxCheckpoints;
    SceneDocument document = base;
    for (size_t i = 0; i < keyframes.size(); ++i) {
        const std::string at = pointer(i);
        if (keep_going && i % 64 == 0 && !keep_going()) throw ValidationError(at, "the check was given up");
        const json& key = keyframes[i];
        if (!key.is_object()) throw ValidationError(at, "a keyframe must be an object {\"time\", \"patch\"}");
        for (const auto& [name, value] : key.items())
            if (name != "time" && name != "patch") throw ValidationError(pointer(i, name), "unknown keyframe field");
        if (!key.contains("time") || !key["time"].is_number())
            throw ValidationError(pointer(i, "time"), "must be a number of seconds");
        const double time = key["time"].get<double>();
        if (!std::isfinite(time) || time < 0.0 || time > kMaxAnimationSeconds)
            throw ValidationError(pointer(i, "time"), "must be between 0 and " + std::to_string(static_cast<int64_t>(kMaxAnimationSeconds)) + " s (a day)");
        if (!times_.empty() && time <= times_.back())
            throw ValidationError(pointer(i, "time"), "must be later than the keyframe before it");
        if (!key.contains("patch") || !key["patch"].is_object())
            throw ValidationError(pointer(i, "patch"), "must be a merge patch (a JSON object)");
        try {
            document = patched(document, key["patch"], limits);
        } catch (const ValidationError& e) {
            throw ValidationError(pointer(i, "patch") + e.pointer(), e.rule());
        }
        times_.push_back(time);
        patches_.push_back(key["patch"]);
        if (i % stride_ == 0) checkpoints_.push_back(document);
    }
    current_document_ = checkpoints_.front();
}

const SceneDocument& Animation::document(size_t i) {
    // From the checkpoint at or before i, unless the current keyframe lies between the two.
    const size_t checkpoint = i / stride_;
    if (current_ > i || current_ < checkpoint * stride_) {
        current_ = checkpoint * stride_;
        current_document_ = checkpoints_[checkpoint];
    }
    while (current_ < i) current_document_ = patched(current_document_, patches_[++current_], limits_);
    return current_document_;
}

SceneDocument Animation::at(double t) {
    const auto next = std::upper_bound(times_.begin(), times_.end(), t);
    if (next == times_.begin()) return document(0);
    if (next == times_.end()) return document(times_.size() - 1);
    const auto i = static_cast<size_t>(next - times_.begin()) - 1;
    if (pair_ != i) {
        pair_from_ = to_json(document(i));
        pair_to_ = to_json(document(i + 1));
        pair_ = i;
    }
    const double u = (t - times_[i]) / (times_[i + 1] - times_[i]);
    return parse_scene(between(pair_from_, pair_to_, u, {}), limits_);
}

}  // namespace refract::protocol
