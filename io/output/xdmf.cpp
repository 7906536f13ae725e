#include "io/output/xdmf.h"

#include <filesystem>
#include <sstream>

namespace nimbus {

namespace {

std::string xml_escape(const std::string& s) {
    std::string out;
    for (char c : s) {
        switch (c) {
            case '&': out += "&amp;"; break;
            case '<': out += "&lt;"; break;
            case '>': out += "&gt;"; break;
            case '"': out += "&quot;"; break;
            case '\'': out += "&apos;"; break;
            default: out.push_back(c);
        }
    }
    return out;
}

std::string attribute_name(const std::string& field) {
    std::string out = field;
    for (char& c : out)
        if (c == '/') c = '_';
    return out;
}

}  // namespace

std::string xdmf_document(const Grid& grid, const std::string& h5_file_name,
                          const std::vector<XdmfField>& fields) {
    const int nx = grid.n[0], ny = grid.n[1], nz = grid.n[2];
    std::ostringstream x;
    x.precision(17);
    x << "<?xml version=\"1.0\" ?>\n"
      << "<!DOCTYPE Xdmf SYSTEM \"Xdmf.dtd\" []>\n"
      << "<Xdmf Version=\"2.0\">\n"
      << "  <Domain>\n"
      << "    <Grid Name=\"nimbus\" GridType=\"Uniform\">\n"
      << "      <Topology TopologyType=\"3DCoRectMesh\" Dimensions=\"" << nz + 1 << ' '
      << ny + 1 << ' ' << nx + 1 << "\"/>\n"
      << "      <Geometry GeometryType=\"ORIGIN_DXDYDZ\">\n"
      << "        <DataItem Name=\"Origin\" Dimensions=\"3\" NumberType=\"Float\" "
         "Precision=\"8\" Format=\"XML\">"
      << grid.origin.z << ' ' << grid.origin.y << ' ' << grid.origin.x << "</DataItem>\n"
      << "        <DataItem Name=\"Spacing\" Dimensions=\"3\" NumberType=\"Float\" "
         "Precision=\"8\" Format=\"XML\">"
      << grid.h << ' ' << grid.h << ' ' << grid.h << "</DataItem>\n"
      << "      </Geometry>\n";
    for (const XdmfField& f : fields) {
        const bool vector = f.ncomp == 3;
        x << "      <Attribute Name=\"" << xml_escape(attribute_name(f.name))
          << "\" AttributeType=\"" << (vector ? "Vector" : "Scalar") << "\" Center=\"Cell\">\n"
          << "        <DataItem Dimensions=\"" << nz << ' ' << ny << ' ' << nx
          << (vector ? " 3" : "") << "\" NumberType=\"Float\" Precision=\"4\" Format=\"HDF\">"
          << xml_escape(h5_file_name) << ":/fields/" << xml_escape(f.name) << "</DataItem>\n"
          << "      </Attribute>\n";
    }
    x << "    </Grid>\n"
      << "  </Domain>\n"
      << "</Xdmf>\n";
    return x.str();
}

std::string xdmf_path_for(const std::string& h5_path) {
    return std::filesystem::path(h5_path).replace_extension(".xdmf").string();
}

}  // namespace nimbus
