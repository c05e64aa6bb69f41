// NumPy .npy arrays (format versions 1.0, 2.0, 3.0). Hand-written: Debian packages no C++
// npy library. The header is a Python dict literal, e.g.
//   {'descr': '<f4', 'fortran_order': False, 'shape': (64, 64, 64), }
// parsed here by a tiny recursive-descent reader that understands just what np.save writes.
#include "io/io_internal.hpp"

namespace gsd::io::detail {

namespace {

constexpr std::string_view kMagic{"\x93NUMPY", 6};

struct NpyHeader {
    std::string descr;
    bool fortran_order = false;
    std::vector<std::size_t> shape;
    std::size_t data_offset = 0;
};

/// Reads the header dict. Every failure names what it expected.
class DictReader {
public:
    DictReader(const std::string& path, std::string_view text) : path_(path), s_(text) {}

    NpyHeader read() {
        NpyHeader h;
        bool have_descr = false, have_order = false, have_shape = false;
        expect('{');
        while (!peek('}')) {
            const std::string key = string_literal();
            expect(':');
            if (key == "descr") {
                if (peek('[')) bad("structured dtypes (a list 'descr') are not supported");
                h.descr = string_literal();
                have_descr = true;
            } else if (key == "fortran_order") {
                h.fortran_order = boolean();
                have_order = true;
            } else if (key == "shape") {
                h.shape = tuple();
                have_shape = true;
            } else {
                bad("unexpected key '" + key + "' in .npy header");
            }
            if (!peek('}')) expect(',');
        }
        expect('}');
        if (!have_descr || !have_order || !have_shape)
            bad(".npy header lacks 'descr', 'fortran_order' or 'shape'");
        return h;
    }

private:
    [[noreturn]] void bad(const std::string& what) const { fail(path_, what); }

    void skip_space() {
        while (i_ < s_.size() && (s_[i_] == ' ' || s_[i_] == '\t' || s_[i_] == '\n' || s_[i_] == '\r')) ++i_;
    }
    bool peek(char c) {
        skip_space();
        return i_ < s_.size() && s_[i_] == c;
    }
    void expect(char c) {
        if (!peek(c)) bad(std::string("malformed .npy header: expected '") + c + "' at offset " + std::to_string(i_));
        ++i_;
    }
    std::string string_literal() {
        skip_space();
        if (i_ >= s_.size() || (s_[i_] != '\'' && s_[i_] != '"'))
            bad("malformed .npy header: expected a quoted string at offset " + std::to_string(i_));
        const char quote = s_[i_++];
        const std::size_t end = s_.find(quote, i_);
        if (end == std::string_view::npos) bad("malformed .npy header: unterminated string");
        std::string out(s_.substr(i_, end - i_));
        i_ = end + 1;
        return out;
    }
    bool boolean() {
        skip_space();
        if (s_.substr(i_, 4) == "True") {
            i_ += 4;
            return true;
        }
        if (s_.substr(i_, 5) == "False") {
            i_ += 5;
            return false;
        }
        bad("malformed .npy header: 'fortran_order' must be True or False");
    }
    /// "()", "(7,)", "(3, 4)"; Python 2's "3L" suffix tolerated.
    std::vector<std::size_t> tuple() {
        expect('(');
        std::vector<std::size_t> dims;
        while (!peek(')')) {
            const std::size_t start = i_;
            while (i_ < s_.size() && s_[i_] >= '0' && s_[i_] <= '9') ++i_;
            long long v = 0;
            if (!parse_int(s_.substr(start, i_ - start), v) || v < 0)
                bad("malformed .npy header: bad dimension in 'shape' at offset " + std::to_string(start));
            if (i_ < s_.size() && s_[i_] == 'L') ++i_;
            dims.push_back(std::size_t(v));
            if (!peek(')')) expect(',');
        }
        expect(')');
        return dims;
    }

    const std::string& path_;
    std::string_view s_;
    std::size_t i_ = 0;
};

NpyHeader read_header(const std::string& path, std::string_view bytes) {
    if (bytes.size() < 10 || bytes.substr(0, 6) != kMagic) fail(path, "not a .npy file (bad magic)");
    const auto major = static_cast<unsigned char>(bytes[6]);
    std::size_t length_bytes = 0;
    if (major == 1) length_bytes = 2;
    else if (major == 2 || major == 3) length_bytes = 4;
    else fail(path, "unsupported .npy format version " + std::to_string(major) + "." +
                        std::to_string(static_cast<unsigned char>(bytes[7])));
    if (bytes.size() < 8 + length_bytes) fail(path, ".npy header is truncated");
    const std::uint64_t header_len = length_bytes == 2 ? load<std::uint16_t>(bytes.data() + 8, std::endian::little)
                                                       : load<std::uint32_t>(bytes.data() + 8, std::endian::little);
    const std::size_t start = 8 + length_bytes;
    if (header_len > bytes.size() - start) fail(path, ".npy header is truncated");
    NpyHeader h = DictReader(path, bytes.substr(start, std::size_t(header_len))).read();
    h.data_offset = start + std::size_t(header_len);
    return h;
}

struct DType {
    char kind;  // 'f' or 'i'
    std::size_t size;
    std::endian order;
};

DType parse_descr(const std::string& path, const std::string& descr) {
    const auto unsupported = [&] {
        fail(path, "unsupported dtype '" + descr + "' (expected float32/float64: '<f4' '>f4' '<f8' '>f8'; "
                   "'<i4' '<i8' are also read)");
    };
    if (descr.size() != 3) unsupported();
    DType t{descr[1], std::size_t(descr[2] - '0'), std::endian::native};
    if (descr[0] == '<') t.order = std::endian::little;
    else if (descr[0] == '>') t.order = std::endian::big;
    else if (descr[0] != '=') unsupported();
    const bool ok = (t.kind == 'f' || t.kind == 'i') && (t.size == 4 || t.size == 8);
    if (!ok) unsupported();
    return t;
}

double value_at(const char* p, const DType& t) {
    if (t.kind == 'f') return t.size == 4 ? double(load<float>(p, t.order)) : load<double>(p, t.order);
    return t.size == 4 ? double(load<std::int32_t>(p, t.order)) : double(load<std::int64_t>(p, t.order));
}

std::string shape_text(const std::vector<std::size_t>& shape) {
    std::string s = "(";
    for (std::size_t i = 0; i < shape.size(); ++i) {
        if (i) s += ", ";
        s += std::to_string(shape[i]);
    }
    return s + (shape.size() == 1 ? ",)" : ")");
}

}  // namespace

void parse_npy_into(const std::string& path, std::string_view bytes, std::vector<std::size_t>& shape,
                    const std::function<double*(std::size_t count)>& storage) {
    const NpyHeader h = read_header(path, bytes);
    if (h.fortran_order)
        fail(path, "Fortran-order (column-major) arrays are not supported; save with "
                   "np.save(path, np.ascontiguousarray(a))");
    const DType t = parse_descr(path, h.descr);
    std::uint64_t count = 1;
    for (std::size_t d : h.shape) count = mul_sat(count, d);
    const std::uint64_t need = mul_sat(count, t.size);
    const std::size_t have = bytes.size() - h.data_offset;
    if (need > have)
        fail(path, ".npy shape " + shape_text(h.shape) + " needs " + std::to_string(need) +
                       " bytes of data but the file has " + std::to_string(have) + " (truncated or corrupt)");
    shape = h.shape;
    double* out = storage(std::size_t(count));
    const char* p = bytes.data() + h.data_offset;
    if (t.kind == 'f' && t.size == 4 && t.order == std::endian::native) {  // the common case, in one tight loop
        for (std::size_t i = 0; i < count; ++i) {
            float f;
            std::memcpy(&f, p + 4 * i, 4);
            out[i] = f;
        }
        return;
    }
    for (std::size_t i = 0; i < count; ++i) out[i] = value_at(p + i * t.size, t);
}

NpyArray parse_npy(const std::string& path, std::string_view bytes) {
    NpyArray a;
    parse_npy_into(path, bytes, a.shape, [&](std::size_t count) {
        a.data.resize(count);
        return a.data.data();
    });
    return a;
}

namespace {

/// The .npy bytes of `count` little-endian values of type T (descr '<f4' or '<i4').
template <class T>
std::string npy_bytes_of(const std::string& path, const std::vector<std::size_t>& shape, const T* values,
                         std::size_t count, const char* descr) {
    std::uint64_t expected = 1;
    for (std::size_t d : shape) expected = mul_sat(expected, d);
    if (expected != count)
        throw Error(path, "shape " + shape_text(shape) + " holds " + std::to_string(expected) + " values, but " +
                              std::to_string(count) + " were given");
    if (count > 0 && values == nullptr) throw Error(path, "no values to write");
    std::string dict = "{'descr': '";
    dict.append(descr).append("', 'fortran_order': False, 'shape': ").append(shape_text(shape)).append(", }");
    // numpy's rule: magic + version + length + header is a multiple of 64, header ends in '\n'.
    const bool v1 = dict.size() + 1 + 10 <= 65535;
    const std::size_t preamble = v1 ? 10 : 12;
    const std::size_t total = (preamble + dict.size() + 1 + 63) / 64 * 64;
    dict.append(total - preamble - dict.size() - 1, ' ');
    dict += '\n';
    std::string out(kMagic);
    out += char(v1 ? 1 : 2);
    out += char(0);
    if (v1) append_le(out, std::uint16_t(dict.size()));
    else append_le(out, std::uint32_t(dict.size()));
    out += dict;
    out.reserve(out.size() + count * sizeof(T));
    for (std::size_t i = 0; i < count; ++i) append_le(out, values[i]);
    return out;
}

}  // namespace

std::string npy_bytes(const std::string& path, const std::vector<std::size_t>& shape, const float* values,
                      std::size_t count) {
    return npy_bytes_of(path, shape, values, count, "<f4");
}

std::string npy_bytes(const std::string& path, const std::vector<std::size_t>& shape, const std::int32_t* values,
                      std::size_t count) {
    return npy_bytes_of(path, shape, values, count, "<i4");
}

PointCloud read_npy_cloud(const std::string& path, std::string_view bytes) {
    const NpyArray a = parse_npy(path, bytes);
    if (a.shape.size() != 2 || (a.shape[1] != 6 && a.shape[1] != 3))
        fail(path, "expected an (N, 6) array (x y z nx ny nz) or (N, 3) (x y z), found shape " + shape_text(a.shape));
    return cloud_from_rows(a.data.data(), a.shape[0], a.shape[1] == 6);
}

std::string npy_cloud_bytes(const PointCloud& cloud) {
    const auto n = std::size_t(cloud.size());
    std::vector<float> rows(n * 6);
    for (std::size_t i = 0; i < n; ++i)
        for (int k = 0; k < 3; ++k) {
            rows[6 * i + k] = float(cloud.points(Eigen::Index(i), k));
            rows[6 * i + 3 + k] = float(cloud.normals(Eigen::Index(i), k));
        }
    return npy_bytes({}, {n, 6}, rows.data(), rows.size());
}

/// Shape in the form np.save writes it; used by io.cpp's messages too.
std::string npy_shape_text(const std::vector<std::size_t>& shape) { return shape_text(shape); }

}  // namespace gsd::io::detail
