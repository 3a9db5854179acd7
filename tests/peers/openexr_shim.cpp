// OpenEXR (the reference library, Debian libopenexr-dev 3.1) in-process for benches/exr.rs:
// decode a file held in memory to interleaved f32 R, G, B(, A) and encode such samples to a file
// in memory, through the C++ API (Imf::InputFile with FLOAT frame-buffer slices, so that
// OpenEXR converts half to float itself; Imf::OutputFile from float samples, or from half
// samples converted here with Imath::half). Every function catches
// OpenEXR's exceptions and returns a non-zero code with the message in `err`. tests/build.rs
// builds this file only when OpenEXR's headers are installed.
#include <ImfChannelList.h>
#include <ImfCompression.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfIO.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <ImfThreading.h>
#include <cstdint>
#include <cstring>
#include <exception>
#include <stdexcept>
#include <vector>

namespace {

// A file held in memory, read in place.
class MemoryIn : public Imf::IStream {
  public:
    MemoryIn(const char *data, size_t len) : Imf::IStream("memory"), data_(data), len_(len), pos_(0) {}
    bool isMemoryMapped() const override { return true; }
    char *readMemoryMapped(int n) override {
        check(n);
        const char *p = data_ + pos_;
        pos_ += static_cast<size_t>(n);
        return const_cast<char *>(p);
    }
    bool read(char c[], int n) override {
        check(n);
        std::memcpy(c, data_ + pos_, static_cast<size_t>(n));
        pos_ += static_cast<size_t>(n);
        return pos_ < len_;
    }
    uint64_t tellg() override { return pos_; }
    void seekg(uint64_t pos) override { pos_ = pos; }

  private:
    void check(int n) const {
        if (n < 0 || pos_ > len_ || static_cast<size_t>(n) > len_ - pos_) {
            throw std::runtime_error("read past the end of the file");
        }
    }
    const char *data_;
    size_t len_;
    size_t pos_;
};

// A file written into the caller's buffer; writing past its end is an error.
class MemoryOut : public Imf::OStream {
  public:
    MemoryOut(char *out, size_t cap) : Imf::OStream("memory"), out_(out), cap_(cap), pos_(0), end_(0) {}
    void write(const char c[], int n) override {
        if (n < 0 || pos_ > cap_ || static_cast<size_t>(n) > cap_ - pos_) {
            throw std::runtime_error("the output buffer is too small");
        }
        std::memcpy(out_ + pos_, c, static_cast<size_t>(n));
        pos_ += static_cast<size_t>(n);
        if (pos_ > end_) {
            end_ = pos_;
        }
    }
    uint64_t tellp() override { return pos_; }
    void seekp(uint64_t pos) override { pos_ = pos; }
    size_t end() const { return end_; }

  private:
    char *out_;
    size_t cap_;
    size_t pos_;
    size_t end_;
};

void set_error(const char *what, char *err, size_t err_len) {
    if (err != nullptr && err_len > 0) {
        std::strncpy(err, what, err_len - 1);
        err[err_len - 1] = '\0';
    }
}

const char *const NAMES[4] = {"R", "G", "B", "A"};

} // namespace

extern "C" {

// OpenEXR's global worker threads: 0 decodes and encodes on the calling thread only.
void openexr_shim_set_threads(int threads) { Imf::setGlobalThreadCount(threads); }

// Size of the data window and whether the first part has an A channel; non-zero on failure.
int openexr_shim_info(const uint8_t *data, size_t len, uint32_t *width, uint32_t *height, int *alpha, char *err,
                      size_t err_len) {
    try {
        MemoryIn in(reinterpret_cast<const char *>(data), len);
        Imf::InputFile file(in, Imf::globalThreadCount());
        const Imath::Box2i dw = file.header().dataWindow();
        *width = static_cast<uint32_t>(dw.max.x - dw.min.x + 1);
        *height = static_cast<uint32_t>(dw.max.y - dw.min.y + 1);
        *alpha = file.header().channels().findChannel("A") != nullptr ? 1 : 0;
        return 0;
    } catch (const std::exception &e) {
        set_error(e.what(), err, err_len);
        return 1;
    }
}

// Decodes the data window's R, G, B (and A when `channels` is 4) as interleaved f32 into `out`
// (`out_len` floats, at least width * height * channels); non-zero on failure.
int openexr_shim_decode(const uint8_t *data, size_t len, float *out, size_t out_len, int channels, char *err,
                        size_t err_len) {
    try {
        if (channels != 3 && channels != 4) {
            throw std::runtime_error("channels must be 3 or 4");
        }
        MemoryIn in(reinterpret_cast<const char *>(data), len);
        Imf::InputFile file(in, Imf::globalThreadCount());
        const Imath::Box2i dw = file.header().dataWindow();
        const size_t w = static_cast<size_t>(dw.max.x - dw.min.x + 1);
        const size_t h = static_cast<size_t>(dw.max.y - dw.min.y + 1);
        if (out_len / w / h < static_cast<size_t>(channels)) {
            throw std::runtime_error("the output buffer is too small");
        }
        const size_t xs = sizeof(float) * channels;
        const size_t ys = xs * w;
        // The slice's base is where pixel (0, 0) of the full coordinate space would be.
        char *base = reinterpret_cast<char *>(out) - static_cast<ptrdiff_t>(dw.min.x) * static_cast<ptrdiff_t>(xs) -
                     static_cast<ptrdiff_t>(dw.min.y) * static_cast<ptrdiff_t>(ys);
        Imf::FrameBuffer fb;
        for (int c = 0; c < channels; c++) {
            fb.insert(NAMES[c], Imf::Slice(Imf::FLOAT, base + c * sizeof(float), xs, ys, 1, 1, c == 3 ? 1.0 : 0.0));
        }
        file.setFrameBuffer(fb);
        file.readPixels(dw.min.y, dw.max.y);
        return 0;
    } catch (const std::exception &e) {
        set_error(e.what(), err, err_len);
        return 1;
    }
}

// Encodes `width` x `height` interleaved f32 samples (`channels` 3 or 4) as a scan-line file of
// `half` (1) or float (0) channels compressed with OpenEXR compression id `compression`, into
// `out` (`cap` bytes); the file's length in `written`. Non-zero on failure.
int openexr_shim_encode(const float *samples, uint32_t width, uint32_t height, int channels, int compression,
                        int half, uint8_t *out, size_t cap, size_t *written, char *err, size_t err_len) {
    try {
        if (channels != 3 && channels != 4) {
            throw std::runtime_error("channels must be 3 or 4");
        }
        if (compression < 0 || compression >= Imf::NUM_COMPRESSION_METHODS) {
            throw std::runtime_error("unknown compression");
        }
        Imf::Header header(static_cast<int>(width), static_cast<int>(height));
        header.compression() = static_cast<Imf::Compression>(compression);
        // OpenEXR's writer does not convert float slices to half channels: half files are
        // written from half samples converted here (as RgbaOutputFile users do).
        const size_t count = static_cast<size_t>(width) * height * channels;
        std::vector<Imath::half> halves(half != 0 ? count : 0);
        for (size_t i = 0; i < halves.size(); i++) {
            halves[i] = Imath::half(samples[i]);
        }
        const Imf::PixelType type = half != 0 ? Imf::HALF : Imf::FLOAT;
        const size_t size = half != 0 ? sizeof(Imath::half) : sizeof(float);
        const char *base = half != 0 ? reinterpret_cast<const char *>(halves.data())
                                     : reinterpret_cast<const char *>(samples);
        const size_t xs = size * channels;
        const size_t ys = xs * width;
        Imf::FrameBuffer fb;
        for (int c = 0; c < channels; c++) {
            header.channels().insert(NAMES[c], Imf::Channel(type));
            fb.insert(NAMES[c], Imf::Slice(type, const_cast<char *>(base + c * size), xs, ys));
        }
        MemoryOut stream(reinterpret_cast<char *>(out), cap);
        {
            Imf::OutputFile file(stream, header, Imf::globalThreadCount());
            file.setFrameBuffer(fb);
            file.writePixels(static_cast<int>(height));
        } // the destructor writes the offset table
        *written = stream.end();
        return 0;
    } catch (const std::exception &e) {
        set_error(e.what(), err, err_len);
        return 1;
    }
}
}
