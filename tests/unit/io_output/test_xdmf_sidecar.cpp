// XDMF sidecar: written by commit() beside the HDF5 file; checked with a minimal XML parser
// (balanced, properly nested tags) and against the HDF5 file itself: every Attribute points at
// an existing dataset, relative to the sidecar, whose shape matches the declared Dimensions.
#include <gtest/gtest.h>
#include <mpi.h>

#include <cctype>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "io/output/hdf5_reader.h"
#include "io/output/hdf5_writer.h"
#include "io/output/xdmf.h"
#include "tests/unit/io_output/sample_fields.h"
#include "tests/support/scratch_dir.h"

namespace nimbus {
namespace {

struct Element {
    std::string name;
    std::map<std::string, std::string> attrs;
    std::string text;
    std::vector<int> children;  // indices into the element list
};

// Just enough XML for the sidecar: declarations, elements, attributes in double quotes, text.
// Returns false on any syntax or nesting error. elements[0] is the root.
bool parse_xml(const std::string& s, std::vector<Element>& elements) {
    std::vector<int> open;
    size_t p = 0;
    while (p < s.size()) {
        if (s[p] != '<') {
            const size_t next = s.find('<', p);
            const std::string text = s.substr(p, next == std::string::npos ? next : next - p);
            if (!open.empty()) elements[open.back()].text += text;
            else if (text.find_first_not_of(" \n\r\t") != std::string::npos) return false;
            if (next == std::string::npos) break;
            p = next;
            continue;
        }
        const size_t close = s.find('>', p);
        if (close == std::string::npos) return false;
        std::string tag = s.substr(p + 1, close - p - 1);
        p = close + 1;
        if (tag.empty()) return false;
        if (tag[0] == '?' || tag[0] == '!') continue;
        if (tag[0] == '/') {
            if (open.empty() || elements[open.back()].name != tag.substr(1)) return false;
            open.pop_back();
            continue;
        }
        const bool self_closing = tag.back() == '/';
        if (self_closing) tag.pop_back();
        Element e;
        size_t q = 0;
        while (q < tag.size() && !std::isspace(static_cast<unsigned char>(tag[q]))) ++q;
        e.name = tag.substr(0, q);
        while (true) {
            while (q < tag.size() && std::isspace(static_cast<unsigned char>(tag[q]))) ++q;
            if (q >= tag.size()) break;
            const size_t eq = tag.find("=\"", q);
            if (eq == std::string::npos) return false;
            const size_t end = tag.find('"', eq + 2);
            if (end == std::string::npos) return false;
            e.attrs[tag.substr(q, eq - q)] = tag.substr(eq + 2, end - eq - 2);
            q = end + 1;
        }
        if (e.name.empty()) return false;
        if (!open.empty()) elements[open.back()].children.push_back(static_cast<int>(elements.size()));
        else if (!elements.empty()) return false;  // a second root
        elements.push_back(e);
        if (!self_closing) open.push_back(static_cast<int>(elements.size()) - 1);
    }
    return open.empty() && !elements.empty();
}

std::string trim(const std::string& s) {
    const size_t a = s.find_first_not_of(" \n\r\t"), b = s.find_last_not_of(" \n\r\t");
    return a == std::string::npos ? "" : s.substr(a, b - a + 1);
}

TEST(XdmfParser, RejectsBrokenXml) {
    std::vector<Element> e;
    EXPECT_FALSE(parse_xml("<a><b></a></b>", e));
    e.clear();
    EXPECT_FALSE(parse_xml("<a><b>", e));
    e.clear();
    EXPECT_TRUE(parse_xml("<?xml?><a x=\"1\"><b/>t</a>", e));
}

TEST(XdmfSidecar, DescribesEveryDatasetWithItsShape) {
    test::ScratchDir dir("xdmf");
    const Grid grid = test::sample_grid();
    Decomposition d(MPI_COMM_WORLD, grid.n);
    const std::string h5 = dir.file("cloud.h5");
    {
        Hdf5Writer w(d, grid, h5);
        test::write_sample_fields(w, d);
        w.commit();
    }
    if (d.rank() != 0) return;

    const std::string xdmf_file = dir.file("cloud.xdmf");
    EXPECT_EQ(xdmf_path_for(h5), xdmf_file);
    std::ifstream in(xdmf_file);
    ASSERT_TRUE(in.good()) << xdmf_file;
    std::stringstream text;
    text << in.rdbuf();
    std::vector<Element> xml;
    ASSERT_TRUE(parse_xml(text.str(), xml)) << text.str();

    ASSERT_EQ(xml[0].name, "Xdmf");
    ASSERT_EQ(xml[0].children.size(), 1u);
    const Element& domain = xml[xml[0].children[0]];
    ASSERT_EQ(domain.name, "Domain");
    ASSERT_EQ(domain.children.size(), 1u);
    const Element& g = xml[domain.children[0]];
    ASSERT_EQ(g.name, "Grid");

    std::map<std::string, std::string> fields;  // attribute name -> "dims|path"
    int topologies = 0, geometries = 0;
    for (int c : g.children) {
        const Element& e = xml[c];
        if (e.name == "Topology") {
            ++topologies;
            EXPECT_EQ(e.attrs.at("TopologyType"), "3DCoRectMesh");
            EXPECT_EQ(e.attrs.at("Dimensions"), "7 5 6");  // nodes: nz+1, ny+1, nx+1
        } else if (e.name == "Geometry") {
            ++geometries;
            EXPECT_EQ(e.attrs.at("GeometryType"), "ORIGIN_DXDYDZ");
            ASSERT_EQ(e.children.size(), 2u);
            EXPECT_EQ(trim(xml[e.children[0]].text), "3.25 2 -1");  // origin z y x
            EXPECT_EQ(trim(xml[e.children[1]].text), "0.5 0.5 0.5");
        } else if (e.name == "Attribute") {
            EXPECT_EQ(e.attrs.at("Center"), "Cell");
            ASSERT_EQ(e.children.size(), 1u);
            const Element& item = xml[e.children[0]];
            EXPECT_EQ(item.attrs.at("Format"), "HDF");
            EXPECT_EQ(item.attrs.at("NumberType"), "Float");
            EXPECT_EQ(item.attrs.at("Precision"), "4");
            fields[e.attrs.at("Name")] =
                e.attrs.at("AttributeType") + "|" + item.attrs.at("Dimensions") + "|" + trim(item.text);
        }
    }
    EXPECT_EQ(topologies, 1);
    EXPECT_EQ(geometries, 1);

    const std::map<std::string, std::string> expected = {
        {"density", "Scalar|6 4 5|cloud.h5:/fields/density"},
        {"fluence_diffuse_r", "Scalar|6 4 5|cloud.h5:/fields/fluence_diffuse/r"},
        {"fluence_diffuse_g", "Scalar|6 4 5|cloud.h5:/fields/fluence_diffuse/g"},
        {"flux_diffuse_r", "Vector|6 4 5 3|cloud.h5:/fields/flux_diffuse/r"},
    };
    EXPECT_EQ(fields, expected);

    // Each reference resolves, relative to the sidecar's folder, to a dataset of that shape.
    for (const auto& [name, desc] : fields) {
        const size_t bar1 = desc.find('|'), bar2 = desc.find('|', bar1 + 1);
        const std::string ref = desc.substr(bar2 + 1);
        const size_t colon = ref.find(':');
        const std::string file = dir.file(ref.substr(0, colon));
        const FieldData f = read_field(file, ref.substr(colon + 1));
        std::ostringstream dims;
        dims << f.shape[2] << ' ' << f.shape[1] << ' ' << f.shape[0];
        if (f.ncomp == 3) dims << " 3";
        EXPECT_EQ(desc.substr(bar1 + 1, bar2 - bar1 - 1), dims.str()) << name;
    }
}

}  // namespace
}  // namespace nimbus
