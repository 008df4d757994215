#include "volume/nvdb_reader.h"

#include <nanovdb/NanoVDB.h>
#include <nanovdb/util/IO.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <functional>
#include <iterator>
#include <limits>
#include <set>

#include "volume/grid_checks.h"

namespace refract::volume {

namespace {

// The layout read, byte offsets taken from NanoVDB.h and util/IO.h (32.4) and held to them here.
constexpr uint64_t kMagic = NANOVDB_MAGIC_NUMBER;  // "NanoVDB0", little-endian
constexpr uint32_t kMajor = NANOVDB_MAJOR_VERSION_NUMBER;
constexpr uint32_t kNewestMinor = NANOVDB_MINOR_VERSION_NUMBER;
constexpr uint64_t kHeaderBytes = 16;  // io::Header: magic, version, grid count (u16), codec (u16)
constexpr uint64_t kMetaBytes = 176;   // io::MetaData, then the name
constexpr uint64_t kMetaGridSize = 0, kMetaFileSize = 8, kMetaNameSize = 136, kMetaCodec = 168;
constexpr uint64_t kGridBytes = 672;  // GridData
constexpr uint64_t kGridVersion = 16, kGridSize = 32, kGridType = 636;
constexpr uint64_t kGridMatrix = 296 + 88, kGridTranslation = 296 + 232;  // Map's mMatD and mVecD (doubles)
constexpr uint64_t kTreeBytes = 64;  // TreeData: 4 x u64 node offsets, 3 x u32 node counts
constexpr uint64_t kTreeCounts = 32;
constexpr uint64_t kRootBytes = 64, kRootTableSize = 24, kRootBackground = 28;
constexpr uint64_t kRootTileBytes = 32, kTileChild = 8, kTileState = 16, kTileValue = 20;
constexpr uint64_t kLeafBytes = 2144, kLeafMask = 16, kLeafValues = 96;

static_assert(sizeof(nanovdb::io::Header) == kHeaderBytes && sizeof(nanovdb::io::MetaData) == kMetaBytes);
static_assert(sizeof(nanovdb::GridData) == kGridBytes &&
              sizeof(nanovdb::NanoTree<float>::DataType) == kTreeBytes);
static_assert(sizeof(nanovdb::NanoRoot<float>::DataType) == kRootBytes);
static_assert(sizeof(nanovdb::NanoRoot<float>::DataType::Tile) == kRootTileBytes);
static_assert(sizeof(nanovdb::NanoLeaf<float>::DataType) == kLeafBytes);

// An internal node of 2^(3 log2dim) entries over children of 2^child_log2 voxels a side.
struct NodeKind {
    const char* name;
    int log2dim, child_log2;
    uint64_t bytes, value_mask, child_mask, table;
};
constexpr NodeKind kUpper{"an upper internal node", 5, 7, 270400, 32, 4128, 8256};
constexpr NodeKind kLower{"a lower internal node", 4, 3, 33856, 32, 544, 1088};
static_assert(sizeof(nanovdb::NanoUpper<float>::DataType) == kUpper.bytes);
static_assert(sizeof(nanovdb::NanoLower<float>::DataType) == kLower.bytes);

// OpenVDB's names of the value types, so that a grid reads the same in a .vdb and a .nvdb.
std::string type_name(uint32_t type) {
    static const char* const kNames[] = {"unknown", "float", "double", "int16",  "int32", "int64", "vec3s",
                                         "vec3d",   "mask",  "half",   "uint32", "bool",  "rgba8", "fp4",
                                         "fp8",     "fp16",  "fpn",    "vec4s",  "vec4d", "index"};
    if (type < std::size(kNames)) return kNames[type];
    return "type #" + std::to_string(type);
}

template <typename T>
T load(std::string_view bytes, uint64_t at) {
    // Every caller has checked its range; this guards against a slip in that, not against the file.
    if (at > bytes.size() || sizeof(T) > bytes.size() - at)
        throw VolumeError("NanoVDB reader: a read past a grid");
    T value;
    std::memcpy(&value, bytes.data() + at, sizeof(T));
    return value;
}

std::string version_text(uint32_t version) {
    return std::to_string(version >> 21) + "." + std::to_string((version >> 10) & 2047) + "." +
           std::to_string(version & 1023);
}

void check_version(uint32_t version, const std::string& what) {
    if ((version >> 21) != kMajor || ((version >> 10) & 2047) > kNewestMinor)
        throw VolumeError("not a readable NanoVDB file: " + what + " is of NanoVDB " + version_text(version) +
                          ", outside what this build reads (" + std::to_string(kMajor) + ".0 to " +
                          std::to_string(kMajor) + "." + std::to_string(kNewestMinor) + ")");
}

void check_codec(uint16_t codec, const std::string& what) {
    if (codec == 0) return;
    const std::string name = codec == 1   ? "ZIP"
                             : codec == 2 ? "BLOSC"
                                          : "unknown codec #" + std::to_string(codec);
    throw VolumeError("a compressed NanoVDB file (" + what + " uses " + name +
                      "); only uncompressed ones are read (write it with codec NONE)");
}

struct FileGrid {
    std::string name;
    std::string_view bytes;  // the grid's buffer: GridData, TreeData, the nodes
};

// Cuts a file into its grids' buffers, every declared size checked against the bytes left.
class FileCursor {
public:
    explicit FileCursor(std::string_view bytes) : bytes_(bytes) {}
    bool done() const { return pos_ == bytes_.size(); }
    std::string_view take(uint64_t length, const std::string& what) {
        const uint64_t left = bytes_.size() - pos_;
        if (length > left)
            throw VolumeError("not a readable NanoVDB file: it ends inside " + what + " (" +
                              std::to_string(length) + " bytes declared, " + std::to_string(left) + " left)");
        const std::string_view taken = bytes_.substr(pos_, length);
        pos_ += length;
        return taken;
    }

private:
    std::string_view bytes_;
    uint64_t pos_ = 0;
};

std::vector<FileGrid> split_file(std::string_view bytes, uint32_t max_grids) {
    FileCursor file(bytes);
    std::vector<FileGrid> grids;
    while (!file.done()) {
        const std::string_view header = file.take(kHeaderBytes, "a segment header");
        const auto magic = load<uint64_t>(header, 0);
        if (magic == __builtin_bswap64(kMagic))
            throw VolumeError("a big-endian NanoVDB file; only little-endian ones are read");
        if (magic != kMagic)
            throw VolumeError(
                header.substr(0, 7) == "NanoVDB"
                    ? "not a readable NanoVDB file: its magic number " + std::string(header.substr(0, 8)) +
                          " is of another NanoVDB generation than this build reads (NanoVDB0, " +
                          std::to_string(kMajor) + ".0 to " + std::to_string(kMajor) + "." +
                          std::to_string(kNewestMinor) + ")"
                    : std::string("not a readable NanoVDB file: a segment does not start with the "
                                  "NanoVDB magic number"));
        check_version(load<uint32_t>(header, 8), "a segment");
        check_codec(load<uint16_t>(header, 14), "a segment");
        const auto count = load<uint16_t>(header, 12);
        if (count == 0) throw VolumeError("not a readable NanoVDB file: a segment of no grids");
        if (grids.size() + count > max_grids)
            throw VolumeError("the file holds " + std::string(grids.empty() ? "" : "at least ") +
                              std::to_string(grids.size() + count) + " grids, more than the limit of " +
                              std::to_string(max_grids));
        std::vector<uint64_t> sizes;
        const size_t first = grids.size();
        for (uint16_t i = 0; i < count; ++i) {
            const std::string_view meta = file.take(kMetaBytes, "a grid's description");
            const auto name_size = load<uint32_t>(meta, kMetaNameSize);
            const std::string_view name = file.take(name_size, "a grid's name");
            grids.push_back({std::string(name.substr(0, name.find('\0'))), {}});
            check_codec(load<uint16_t>(meta, kMetaCodec),
                        "grid " + grid_label(grids.back().name, grids.size() - 1));
            sizes.push_back(load<uint64_t>(meta, kMetaGridSize));
            if (load<uint64_t>(meta, kMetaFileSize) != sizes.back())
                throw VolumeError("not a readable NanoVDB file: grid " +
                                  grid_label(grids.back().name, grids.size() - 1) +
                                  " is stored in another size than its own, uncompressed");
        }
        for (size_t i = first; i < grids.size(); ++i)
            grids[i].bytes = file.take(sizes[i - first], "grid " + grid_label(grids[i].name, i));
    }
    return grids;
}

// A node array of the tree: `count` nodes of `stride` bytes from `begin` (within the grid's buffer).
struct NodeArray {
    uint64_t begin = 0, count = 0, stride = 0;
    std::vector<bool> reached;
};

// A float grid's tree, its arrays checked to lie within the buffer, walked from the root down: every
// child offset must land on a node of the array below, each reached once.
class TreeWalk {
public:
    using LeafVisit = std::function<void(const std::array<int32_t, 3>& origin, uint64_t at)>;
    // A tile of `side`^3 voxels, all of `value`.
    using TileVisit = std::function<void(const std::array<int32_t, 3>& origin, int64_t side, float value)>;

    TreeWalk(std::string_view grid, std::string what);
    float background() const { return load<float>(grid_, root_ + kRootBackground); }
    // Walks the tree; throws VolumeError at a node out of place. Every listed node is reached.
    void walk(const LeafVisit& on_leaf, const TileVisit& on_tile);

private:
    NodeArray array(int level, uint64_t stride);
    uint64_t locate(uint64_t parent, int64_t offset, NodeArray& nodes, const char* name);
    void walk_internal(const NodeKind& kind, uint64_t at, const std::array<int32_t, 3>& origin,
                       const LeafVisit& on_leaf, const TileVisit& on_tile);
    [[noreturn]] void damaged(const std::string& why) const {
        throw VolumeError("not a readable NanoVDB file: grid " + what_ + " " + why);
    }

    std::string_view grid_;
    std::string what_;
    uint64_t root_ = 0, table_size_ = 0;
    NodeArray leaves_, lowers_, uppers_;
};

TreeWalk::TreeWalk(std::string_view grid, std::string what) : grid_(grid), what_(std::move(what)) {
    leaves_ = array(0, kLeafBytes);
    lowers_ = array(1, kLower.bytes);
    uppers_ = array(2, kUpper.bytes);
    const auto root_offset = load<uint64_t>(grid_, kGridBytes + 3 * 8);
    if (root_offset > grid_.size() - kGridBytes || grid_.size() - kGridBytes - root_offset < kRootBytes)
        damaged("has its root beyond its buffer");
    root_ = kGridBytes + root_offset;
    table_size_ = load<uint32_t>(grid_, root_ + kRootTableSize);
    if (table_size_ > (grid_.size() - root_ - kRootBytes) / kRootTileBytes)
        damaged("has a root of " + std::to_string(table_size_) + " tiles, beyond its buffer");
}

NodeArray TreeWalk::array(int level, uint64_t stride) {
    const auto offset = load<uint64_t>(grid_, kGridBytes + 8 * uint64_t(level));
    const auto count = load<uint32_t>(grid_, kGridBytes + kTreeCounts + 4 * uint64_t(level));
    static const char* const kNames[] = {"leaves", "lower internal nodes", "upper internal nodes"};
    if (count != 0 &&
        (offset > grid_.size() - kGridBytes || count > (grid_.size() - kGridBytes - offset) / stride))
        damaged("lists " + std::to_string(count) + " " + kNames[level] + " at byte " +
                std::to_string(offset) + " of its tree, beyond its buffer of " +
                std::to_string(grid_.size()) + " bytes");
    NodeArray nodes{kGridBytes + (count ? offset : 0), count, stride, {}};
    nodes.reached.assign(count, false);
    return nodes;
}

uint64_t TreeWalk::locate(uint64_t parent, int64_t offset, NodeArray& nodes, const char* name) {
    constexpr int64_t kFar = int64_t{1} << 62;
    const int64_t at = offset > -kFar && offset < kFar ? int64_t(parent) + offset : -1;
    if (at < int64_t(nodes.begin) || uint64_t(at) - nodes.begin >= nodes.count * nodes.stride ||
        (uint64_t(at) - nodes.begin) % nodes.stride != 0)
        damaged("has a child offset that does not lead to " + std::string(name) + " of its tree");
    const uint64_t index = (uint64_t(at) - nodes.begin) / nodes.stride;
    if (nodes.reached[index]) damaged("reaches " + std::string(name) + " twice");
    nodes.reached[index] = true;
    return uint64_t(at);
}

void TreeWalk::walk(const LeafVisit& on_leaf, const TileVisit& on_tile) {
    for (NodeArray* nodes : {&leaves_, &lowers_, &uppers_}) nodes->reached.assign(nodes->count, false);
    std::set<std::array<int32_t, 3>> origins;
    for (uint64_t t = 0; t < table_size_; ++t) {
        const uint64_t tile = root_ + kRootBytes + t * kRootTileBytes;
        // The key packs x, y and z >> 12 in 21 bits each; the origin is taken as NanoVDB takes it, modulo
        // 2^32.
        const auto key = load<uint64_t>(grid_, tile);
        const std::array<int32_t, 3> origin{int32_t(uint32_t(((key >> 42) & 0x1fffff) << 12)),
                                            int32_t(uint32_t(((key >> 21) & 0x1fffff) << 12)),
                                            int32_t(uint32_t((key & 0x1fffff) << 12))};
        const auto child = load<int64_t>(grid_, tile + kTileChild);
        const bool active = load<uint32_t>(grid_, tile + kTileState) != 0;
        if (child == 0 && !active) continue;
        if (!origins.insert(origin).second) damaged("has two root entries at one origin");
        if (child != 0)
            walk_internal(kUpper, locate(root_, child, uppers_, kUpper.name), origin, on_leaf, on_tile);
        else
            on_tile(origin, 4096, load<float>(grid_, tile + kTileValue));
    }
    for (const NodeArray* nodes : {&leaves_, &lowers_, &uppers_})
        if (std::count(nodes->reached.begin(), nodes->reached.end(), true) != std::ptrdiff_t(nodes->count))
            damaged("lists nodes its tree does not reach");
}

void TreeWalk::walk_internal(const NodeKind& kind, uint64_t at, const std::array<int32_t, 3>& origin,
                             const LeafVisit& on_leaf, const TileVisit& on_tile) {
    const uint32_t entries = 1u << (3 * kind.log2dim), side = 1u << kind.log2dim;
    for (uint32_t word = 0; word < entries / 64; ++word) {
        const auto values = load<uint64_t>(grid_, at + kind.value_mask + 8 * word);
        const auto children = load<uint64_t>(grid_, at + kind.child_mask + 8 * word);
        if ((values & children) != 0)
            damaged("has " + std::string(kind.name) + " with a child and a tile at one place");
        for (uint64_t bits = values | children; bits != 0; bits &= bits - 1) {
            const uint32_t n = word * 64 + uint32_t(std::countr_zero(bits));
            const std::array<int32_t, 3> at_child{
                origin[0] + int32_t((n >> (2 * kind.log2dim)) << kind.child_log2),
                origin[1] + int32_t(((n >> kind.log2dim) & (side - 1)) << kind.child_log2),
                origin[2] + int32_t((n & (side - 1)) << kind.child_log2)};
            const uint64_t entry = at + kind.table + 8 * uint64_t(n);
            if ((values >> (n % 64)) & 1) {
                on_tile(at_child, int64_t{1} << kind.child_log2, load<float>(grid_, entry));
            } else if (kind.log2dim == kUpper.log2dim) {
                walk_internal(kLower, locate(at, load<int64_t>(grid_, entry), lowers_, kLower.name), at_child,
                              on_leaf, on_tile);
            } else {
                on_leaf(at_child, locate(at, load<int64_t>(grid_, entry), leaves_, "a leaf"));
            }
        }
    }
}

// A float grid's map, checked: finite, invertible, with a finite positive voxel size.
std::array<double, 12> index_to_world(std::string_view grid, const std::string& what, GridSummary& summary) {
    std::array<double, 12> m{};
    for (uint64_t row = 0; row < 3; ++row) {
        for (uint64_t column = 0; column < 3; ++column)
            m[row * 4 + column] = load<double>(grid, kGridMatrix + 8 * (row * 3 + column));
        m[row * 4 + 3] = load<double>(grid, kGridTranslation + 8 * row);
    }
    for (double entry : m)
        if (!std::isfinite(entry)) throw VolumeError("grid " + what + " has a transform that is not finite");
    for (size_t axis = 0; axis < 3; ++axis) {
        // As OpenVDB's linear maps measure it: the length of the image of an index step along the axis.
        summary.voxel_size[axis] =
            std::sqrt(m[axis] * m[axis] + m[4 + axis] * m[4 + axis] + m[8 + axis] * m[8 + axis]);
        if (!std::isfinite(summary.voxel_size[axis]) || summary.voxel_size[axis] <= 0)
            throw VolumeError("grid " + what + " has a voxel size that is not finite and positive");
    }
    const double det = m[0] * (m[5] * m[10] - m[6] * m[9]) - m[1] * (m[4] * m[10] - m[6] * m[8]) +
                       m[2] * (m[4] * m[9] - m[5] * m[8]);
    if (!std::isfinite(det) || det == 0)
        throw VolumeError("grid " + what + " has a transform that is not invertible");
    return m;
}

// What a float grid's walk found: its active box, voxels, the leaves its export takes, its first bad value.
struct Survey {
    std::array<int64_t, 3> lo{}, hi{};
    uint64_t active_voxels = 0, export_leaves = 0;
    bool any = false;
    float bad = 0;
    bool has_bad = false;

    void add(const std::array<int32_t, 3>& origin, int64_t side, uint64_t voxels, float value) {
        for (size_t a = 0; a < 3; ++a) {
            lo[a] = any ? std::min(lo[a], int64_t{origin[a]}) : origin[a];
            hi[a] = any ? std::max(hi[a], origin[a] + side - 1) : origin[a] + side - 1;
        }
        any = true;
        active_voxels = active_voxels + voxels < active_voxels ? UINT64_MAX : active_voxels + voxels;
        if (!has_bad && !(std::isfinite(value) && value >= 0)) {
            bad = value;
            has_bad = true;
        }
    }
};

Survey survey(TreeWalk& tree, std::string_view grid) {
    Survey s;
    tree.walk(
        [&](const std::array<int32_t, 3>& origin, uint64_t at) {
            ++s.export_leaves;
            for (uint64_t word = 0; word < 8; ++word)
                for (uint64_t bits = load<uint64_t>(grid, at + kLeafMask + 8 * word); bits != 0;
                     bits &= bits - 1) {
                    const uint64_t n = word * 64 + uint64_t(std::countr_zero(bits));
                    const std::array<int32_t, 3> voxel{origin[0] + int32_t(n >> 6),
                                                       origin[1] + int32_t((n >> 3) & 7),
                                                       origin[2] + int32_t(n & 7)};
                    s.add(voxel, 1, 1, load<float>(grid, at + kLeafValues + 4 * n));
                }
        },
        [&](const std::array<int32_t, 3>& origin, int64_t side, float value) {
            const uint64_t leaves_per_side = uint64_t(side) / kLeafSide;
            s.export_leaves += leaves_per_side * leaves_per_side * leaves_per_side;
            s.add(origin, side, uint64_t(side) * uint64_t(side) * uint64_t(side), value);
        });
    return s;
}

// A float grid checked whole: its map, its tree, its values and box against the limits.
struct CheckedGrid {
    GridSummary summary;
    std::array<double, 12> index_to_world{};
    uint64_t export_leaves = 0;
};

void check_float_grid(std::string_view grid, const std::string& what, const VolumeLimits& limits,
                      CheckedGrid& out) {
    GridSummary& summary = out.summary;
    out.index_to_world = index_to_world(grid, what, summary);
    TreeWalk tree(grid, what);
    const Survey s = survey(tree, grid);
    if (!s.any) {
        summary.unusable_reason = "no active voxels";
        return;
    }
    check_active_box({s.hi[0] - s.lo[0] + 1, s.hi[1] - s.lo[1] + 1, s.hi[2] - s.lo[2] + 1}, what, limits);
    check_grid_value(tree.background(), what, "as its background");
    if (s.has_bad) check_grid_value(s.bad, what, "in an active voxel");
    summary.active_voxels = s.active_voxels;
    out.export_leaves = s.export_leaves;
    const auto& m = out.index_to_world;
    summary.world_min.fill(std::numeric_limits<double>::infinity());
    summary.world_max.fill(-std::numeric_limits<double>::infinity());
    for (size_t a = 0; a < 3; ++a) {
        summary.index_min[a] = int32_t(s.lo[a]);
        summary.index_max[a] = int32_t(s.hi[a]);
    }
    // The world box holds the index box's eight corners (voxel centres at integer coordinates).
    for (int corner = 0; corner < 8; ++corner) {
        const std::array<double, 3> index{double((corner & 1) ? s.hi[0] : s.lo[0]),
                                          double((corner & 2) ? s.hi[1] : s.lo[1]),
                                          double((corner & 4) ? s.hi[2] : s.lo[2])};
        for (size_t row = 0; row < 3; ++row) {
            const double world = index[0] * m[row * 4] + index[1] * m[row * 4 + 1] +
                                 index[2] * m[row * 4 + 2] + m[row * 4 + 3];
            summary.world_min[row] = std::min(summary.world_min[row], world);
            summary.world_max[row] = std::max(summary.world_max[row], world);
        }
    }
    summary.usable = true;
}

// One grid of the file checked: its header, and a float grid whole. Others are listed unusable.
CheckedGrid check_grid(const FileGrid& file_grid, size_t index, const VolumeLimits& limits) {
    const std::string_view grid = file_grid.bytes;
    const std::string what = grid_label(file_grid.name, index);
    if (grid.size() < kGridBytes + kTreeBytes)
        throw VolumeError("not a readable NanoVDB file: grid " + what + " is shorter than its header");
    if (load<uint64_t>(grid, 0) != kMagic)
        throw VolumeError("not a readable NanoVDB file: grid " + what +
                          " does not start with NanoVDB's magic number");
    check_version(load<uint32_t>(grid, kGridVersion), "grid " + what);
    if (load<uint64_t>(grid, kGridSize) != grid.size())
        throw VolumeError("not a readable NanoVDB file: grid " + what + " declares " +
                          std::to_string(load<uint64_t>(grid, kGridSize)) + " bytes where the file holds " +
                          std::to_string(grid.size()));
    CheckedGrid out;
    out.summary.name = file_grid.name;
    const auto type = load<uint32_t>(grid, kGridType);
    out.summary.type = type_name(type);
    if (type == uint32_t(nanovdb::GridType::Float))
        check_float_grid(grid, what, limits, out);
    else
        out.summary.unusable_reason = "a " + out.summary.type + " grid; only float grids are read";
    return out;
}

}  // namespace

bool is_nanovdb(std::string_view bytes) {
    // Any generation's magic ("NanoVDB" and a digit), and the first's byte-swapped (a big-endian file).
    return bytes.size() >= 8 && ((bytes.substr(0, 7) == "NanoVDB" && bytes[7] >= '0' && bytes[7] <= '9') ||
                                 bytes.substr(0, 8) == "0BDVonaN");
}

std::vector<GridSummary> inspect_nvdb(std::string_view bytes, const VolumeLimits& limits) {
    const std::vector<FileGrid> grids = split_file(bytes, limits.max_grids);
    std::vector<GridSummary> summaries;
    for (size_t i = 0; i < grids.size(); ++i) summaries.push_back(check_grid(grids[i], i, limits).summary);
    return summaries;
}

DensityGrid export_nvdb_density(std::string_view bytes, const std::string& grid_name,
                                const VolumeLimits& limits, uint64_t max_leaves) {
    const std::vector<FileGrid> grids = split_file(bytes, limits.max_grids);
    for (size_t i = 0; i < grids.size(); ++i) {
        if (grids[i].name != grid_name) continue;
        const CheckedGrid checked = check_grid(grids[i], i, limits);
        if (checked.summary.type != "float") continue;
        if (!checked.summary.usable)
            throw VolumeError("grid " + quoted(grid_name) + " has " + checked.summary.unusable_reason);
        if (checked.export_leaves > max_leaves)
            throw VolumeError("grid " + quoted(grid_name) + " has " + std::to_string(checked.export_leaves) +
                              " leaves of 8^3 voxels, more than the " + std::to_string(max_leaves) +
                              " a scene takes");
        const std::string_view grid = grids[i].bytes;
        DensityGrid out;
        out.index_to_world = checked.index_to_world;
        out.leaves.reserve(checked.export_leaves);
        TreeWalk tree(grid, quoted(grid_name));
        tree.walk(
            [&](const std::array<int32_t, 3>& origin, uint64_t at) {
                DensityLeaf& leaf = out.leaves.emplace_back();
                leaf.origin = origin;
                for (uint64_t word = 0; word < 8; ++word) {
                    const auto mask = load<uint64_t>(grid, at + kLeafMask + 8 * word);
                    for (uint64_t bit = 0; bit < 64; ++bit)
                        if ((mask >> bit) & 1)
                            leaf.values[word * 64 + bit] =
                                load<float>(grid, at + kLeafValues + 4 * (word * 64 + bit));
                }
            },
            [&](const std::array<int32_t, 3>& origin, int64_t side, float value) {
                for (int32_t x = 0; x < side; x += kLeafSide)
                    for (int32_t y = 0; y < side; y += kLeafSide)
                        for (int32_t z = 0; z < side; z += kLeafSide) {
                            DensityLeaf& leaf = out.leaves.emplace_back();
                            leaf.origin = {origin[0] + x, origin[1] + y, origin[2] + z};
                            leaf.values.fill(value);
                        }
            });
        return out;
    }
    throw VolumeError("no float grid named " + quoted(grid_name) + " in the file");
}

}  // namespace refract::volume
