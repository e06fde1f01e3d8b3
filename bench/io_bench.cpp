// Reading and writing the default phantom CT (512 x 512 x 80 int16, 40 MiB) in every format,
// beside the floor that any reader must pay: reading or writing the same bytes with stdio.
// Counters: MiB/s of image data and the file size relative to the raw bytes.
#include "lobe/io/hdf5.h"
#include "lobe/io/metaimage.h"
#include "lobe/io/nifti.h"
#include "lphantom/phantom.h"

#include <benchmark/benchmark.h>
#include <hdf5.h>

#include <cstdio>
#include <filesystem>
#include <vector>

namespace fs = std::filesystem;
using namespace lobe;

namespace {

const core::ImageI16& ct()
{
    static const core::ImageI16 image = phantom::generate_phantom().ct;
    return image;
}

// One folder per case, so that the file size counter sees only that format's files.
fs::path case_file(const std::string& name)
{
    ct(); // generate the phantom before any timing starts
    const fs::path dir = fs::temp_directory_path() / "lobe-io-bench" / name;
    fs::create_directories(dir);
    return dir / name;
}

std::size_t bytes() { return ct().data.size() * sizeof(std::int16_t); }

void report(benchmark::State& state, const fs::path& file)
{
    state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations()) * static_cast<std::int64_t>(bytes()));
    std::size_t size = 0; // every file the format wrote (header + data, .h5 + .xdmf)
    for (const auto& e : fs::directory_iterator(file.parent_path()))
        size += fs::file_size(e.path());
    state.counters["file_vs_raw"] = static_cast<double>(size) / static_cast<double>(bytes());
}

void write_in(const fs::path& p)
{
    const auto ext = p.extension().string();
    if (ext == ".h5" && p.stem().string().find("gzip4") != std::string::npos) {
        io::Hdf5WriteParams params; // the container's default before 2026-11-27, for comparison
        params.gzip_level = 4;
        io::Hdf5Writer w(p, params);
        w.write_image("ct", ct());
        w.commit();
    } else if (ext == ".h5")
        io::write_hdf5_image(p, ct(), "ct");
    else if (ext == ".nii" || ext == ".gz")
        io::write_nifti(p, ct());
    else {
        io::MetaImageWriteParams params;
        params.compress = p.stem().string().find("zlib") != std::string::npos;
        if (p.stem().string().find("zlib6") != std::string::npos)
            params.compression_level = 6; // zlib's own default, for comparison with lobe's 1
        io::write_metaimage(p, ct(), params);
    }
}

core::AnyImage read_in(const fs::path& p)
{
    const auto ext = p.extension().string();
    if (ext == ".h5")
        return io::read_hdf5_image(p, "ct");
    if (ext == ".nii" || ext == ".gz")
        return io::read_nifti(p);
    return io::read_metaimage(p);
}

void BM_StdioWrite(benchmark::State& state)
{
    const auto p = case_file("stdio.raw");
    for (auto _ : state) {
        // A new file each time, as lobe's writers make (temporary + rename): truncating the old
        // one would make ext4 flush it first (auto_da_alloc) and time the disk instead.
        fs::remove(p);
        std::FILE* f = std::fopen(p.c_str(), "wb");
        std::fwrite(ct().data.data(), 1, bytes(), f);
        std::fclose(f);
    }
    report(state, p);
}

void BM_StdioRead(benchmark::State& state)
{
    const auto p = case_file("stdio.raw");
    std::vector<std::int16_t> buf(ct().data.size());
    for (auto _ : state) {
        std::FILE* f = std::fopen(p.c_str(), "rb");
        benchmark::DoNotOptimize(std::fread(buf.data(), 1, bytes(), f));
        std::fclose(f);
    }
    report(state, p);
}

void BM_Write(benchmark::State& state, const char* name)
{
    const auto p = case_file(name);
    for (auto _ : state)
        write_in(p);
    report(state, p);
}

void BM_Read(benchmark::State& state, const char* name)
{
    const auto p = case_file(name);
    write_in(p);
    for (auto _ : state)
        benchmark::DoNotOptimize(read_in(p));
    report(state, p);
}

// The peer for lobe's container write: the same dataset (128 x 128 x 32 chunks, shuffle, deflate at
// the container's default level, Fletcher-32) written with H5Dwrite, so that HDF5 runs its own
// filter pipeline, on one thread.
void BM_Hdf5OwnPipeline(benchmark::State& state)
{
    const auto p = case_file("hdf5_own.h5");
    const auto& im = ct();
    const hsize_t dims[3] = {hsize_t(im.size[2]), hsize_t(im.size[1]), hsize_t(im.size[0])};
    const hsize_t chunk[3] = {32, 128, 128};
    for (auto _ : state) {
        fs::remove(p);
        const hid_t f = H5Fcreate(p.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
        const hid_t space = H5Screate_simple(3, dims, nullptr);
        const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
        H5Pset_chunk(dcpl, 3, chunk);
        H5Pset_shuffle(dcpl);
        H5Pset_deflate(dcpl, static_cast<unsigned>(io::Hdf5WriteParams{}.gzip_level));
        H5Pset_fletcher32(dcpl);
        const hid_t ds = H5Dcreate2(f, "ct", H5T_STD_I16LE, space, H5P_DEFAULT, dcpl, H5P_DEFAULT);
        if (ds < 0 || H5Dwrite(ds, H5T_NATIVE_INT16, H5S_ALL, H5S_ALL, H5P_DEFAULT, im.data.data()) < 0)
            state.SkipWithError("HDF5 write failed");
        H5Dclose(ds);
        H5Pclose(dcpl);
        H5Sclose(space);
        H5Fclose(f);
    }
    report(state, p);
}

// The peer for lobe's container read: HDF5's own pipeline (H5Dread, one thread) on the same file.
void BM_Hdf5OwnRead(benchmark::State& state)
{
    const auto p = case_file("ct.h5");
    write_in(p);
    std::vector<std::int16_t> buf(ct().data.size());
    for (auto _ : state) {
        const hid_t f = H5Fopen(p.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
        const hid_t ds = H5Dopen2(f, "/images/ct", H5P_DEFAULT);
        if (ds < 0 || H5Dread(ds, H5T_NATIVE_INT16, H5S_ALL, H5S_ALL, H5P_DEFAULT, buf.data()) < 0)
            state.SkipWithError("HDF5 read failed");
        H5Dclose(ds);
        H5Fclose(f);
    }
    report(state, p);
}

} // namespace

BENCHMARK(BM_StdioWrite)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_StdioRead)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Write, metaimage_raw, "ct_raw.mhd")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Read, metaimage_raw, "ct_raw.mhd")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Write, metaimage_zlib, "ct_zlib.mha")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Read, metaimage_zlib, "ct_zlib.mha")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Write, metaimage_zlib6, "ct_zlib6.mha")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Read, metaimage_zlib6, "ct_zlib6.mha")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Write, nifti, "ct.nii")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Read, nifti, "ct.nii")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Write, nifti_gz, "ct.nii.gz")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Read, nifti_gz, "ct.nii.gz")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Write, hdf5_gzip, "ct.h5")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Write, hdf5_gzip4, "ct_gzip4.h5")->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Hdf5OwnPipeline)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Read, hdf5_gzip, "ct.h5")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Read, hdf5_gzip4, "ct_gzip4.h5")->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Hdf5OwnRead)->Unit(benchmark::kMillisecond);

BENCHMARK_MAIN();
