#include "volume/vdb_layout.h"

#include <cstring>

#include "volume/vdb_reader.h"

namespace refract::volume {

namespace {

// Magic number, format version, library version, the has-offsets flag and the UUID, in every file
// version read (222 and later).
constexpr size_t kHeaderBytes = 8 + 4 + 8 + 1 + 36;

class Cursor {
public:
    Cursor(std::string_view bytes, size_t pos) : bytes_(bytes), pos_(pos) {}
    size_t pos() const { return pos_; }

    std::string_view take(uint64_t length, const std::string& what) {
        const size_t left = bytes_.size() - pos_;
        if (length > left)
            throw VolumeError("not a readable OpenVDB file: it ends inside " + what + " (" +
                              std::to_string(length) + " bytes declared, " + std::to_string(left) + " left)");
        const std::string_view taken = bytes_.substr(pos_, static_cast<size_t>(length));
        pos_ += static_cast<size_t>(length);
        return taken;
    }
    template <typename T>
    T number(const std::string& what) {
        T value;
        std::memcpy(&value, take(sizeof value, what).data(), sizeof value);
        return value;
    }
    std::string_view string(const std::string& what) { return take(number<uint32_t>(what), what); }

private:
    std::string_view bytes_;
    size_t pos_;
};

// A metadata map as OpenVDB writes it: a count, then per entry a name, a type name and a value, each
// preceded by its length.
void walk_metadata(Cursor& at, const std::string& whose) {
    const auto count = at.number<uint32_t>("the metadata count of " + whose);
    for (uint32_t i = 0; i < count; ++i) {
        at.string("a metadata name of " + whose);
        at.string("a metadata type of " + whose);
        at.take(at.number<uint32_t>("a metadata value of " + whose), "a metadata value of " + whose);
    }
}

}  // namespace

std::vector<std::string> split_grids(std::string_view bytes, uint32_t max_grids) {
    Cursor at(bytes, 0);
    at.take(kHeaderBytes, "the header");
    walk_metadata(at, "the file");
    const std::string_view head = bytes.substr(0, at.pos());
    const auto count = at.number<int32_t>("the grid count");
    if (count <= 0) throw VolumeError("the file holds no grids");
    if (static_cast<uint32_t>(count) > max_grids)
        throw VolumeError("the file holds " + std::to_string(count) + " grids, more than the limit of " +
                          std::to_string(max_grids));

    std::vector<std::string> streams;
    for (int32_t i = 0; i < count; ++i) {
        const size_t descriptor_begin = at.pos();
        const std::string what =
            "grid '" + std::string(at.string("the name of grid #" + std::to_string(i))) + "'";
        at.string("the type of " + what);
        if (!at.string("the instance parent of " + what).empty())
            throw VolumeError(what + " is an instance of another grid; instanced grids are not read");
        const std::string_view descriptor = bytes.substr(descriptor_begin, at.pos() - descriptor_begin);
        const auto grid_pos = at.number<int64_t>("the offsets of " + what);
        at.number<int64_t>("the offsets of " + what);
        const auto end_pos = at.number<int64_t>("the offsets of " + what);
        size_t begin = at.pos(), end = bytes.size();
        if (end_pos != 0) {
            if (grid_pos < static_cast<int64_t>(at.pos()) || end_pos < grid_pos ||
                end_pos > static_cast<int64_t>(bytes.size()))
                throw VolumeError("not a readable OpenVDB file: the offsets of " + what +
                                  " lie outside it (truncated?)");
            begin = static_cast<size_t>(grid_pos);
            end = static_cast<size_t>(end_pos);
        } else if (count > 1) {
            // Written as a stream: a grid ends where its tree does, found only by reading the tree.
            throw VolumeError(
                "the file holds " + std::to_string(count) +
                " grids without offsets to their ends (written as a stream): only a single-grid "
                "stream can be checked before it is read; write it as a file");
        }
        // What OpenVDB reads of the grid before its tree: compression flags, metadata, the transform's type.
        Cursor grid(bytes.substr(0, end), begin);
        grid.number<uint32_t>("the compression flags of " + what);
        walk_metadata(grid, what);
        grid.string("the transform type of " + what);

        std::string stream(head);
        const int32_t one = 1;
        stream.append(reinterpret_cast<const char*>(&one), sizeof one);
        stream.append(descriptor);
        stream.append(3 * sizeof(int64_t), '\0');  // no offsets: the grid follows, read as a stream
        stream.append(bytes.substr(begin, end - begin));
        streams.push_back(std::move(stream));
        at = Cursor(bytes, end);
    }
    return streams;
}

}  // namespace refract::volume
