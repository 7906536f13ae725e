#include "io/output/output_files.h"

#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <random>
#include <system_error>

#include "src/core/error.h"

namespace nimbus {

namespace fs = std::filesystem;

namespace {

int rank_of(MPI_Comm comm) {
    int rank = 0;
    MPI_Comm_rank(comm, &rank);
    return rank;
}

// "<pid>-<8 hex digits>": the pid tells runs on one host apart, the random part runs on
// different hosts sharing a folder.
std::string draw_token() {
    char text[32];
    std::snprintf(text, sizeof(text), "%ld-%08x", static_cast<long>(::getpid()),
                  static_cast<unsigned>(std::random_device{}()));
    return text;
}

}  // namespace

OutputFiles::OutputFiles(MPI_Comm comm) : comm_(comm) {
    char token[32] = {};
    if (rank_of(comm) == 0) draw_token().copy(token, sizeof(token) - 1);
    MPI_Bcast(token, sizeof(token), MPI_CHAR, 0, comm);
    token_ = token;
}

OutputFiles::~OutputFiles() {
    if (committed_ || rank_of(comm_) != 0) return;
    std::error_code ec;
    for (const auto& [tmp, final_path] : files_) fs::remove(tmp, ec);
}

std::string OutputFiles::add(const std::string& final_path) {
    files_.emplace_back(final_path + "." + token_ + ".tmp", final_path);
    return files_.back().first;
}

std::string OutputFiles::with_final_names(std::string message) const {
    for (const auto& [tmp, final_path] : files_)
        for (size_t at = message.find(tmp); at != std::string::npos;
             at = message.find(tmp, at + final_path.size()))
            message.replace(at, tmp.size(), final_path);
    return message;
}

void OutputFiles::commit() {
    if (committed_) throw Error("output files are already committed");
    committed_ = true;  // from here on, commit() itself cleans up after a failure
    // No rank sees a final name before every rank has entered commit (and so is done with
    // the files): without this, rank 0 could rename while another rank still checks them.
    MPI_Barrier(comm_);
    std::string message;
    if (rank_of(comm_) == 0) {
        std::error_code ec;
        size_t renamed = 0;
        for (; renamed < files_.size(); ++renamed) {
            const auto& [tmp, final_path] = files_[renamed];
            fs::rename(tmp, final_path, ec);
            if (ec) {
                message = "cannot write output file '" + final_path + "': " + ec.message();
                break;
            }
        }
        if (!message.empty()) {
            for (size_t n = 0; n < files_.size(); ++n)
                fs::remove(n < renamed ? files_[n].second : files_[n].first, ec);
        }
    }
    check_collective(comm_, message.empty(), message);
}

}  // namespace nimbus
