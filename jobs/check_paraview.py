# Opens a nimbus XDMF sidecar in ParaView and prints what ParaView sees: the grid and every
# cell array with its range. Needs Debian's paraview + python3-paraview (not installed by
# jobs/install_deps.sh: they are large). Usage: pvbatch3.11 jobs/check_paraview.py out/nimbus.xdmf
import sys
from paraview.simple import XDMFReader, UpdatePipeline, servermanager
r = XDMFReader(FileNames=[sys.argv[1]])
UpdatePipeline(proxy=r)
data = servermanager.Fetch(r)
print("class", data.GetClassName(), "cells", data.GetNumberOfCells(), "dims", data.GetDimensions() if hasattr(data, "GetDimensions") else "")
cd = data.GetCellData()
for i in range(cd.GetNumberOfArrays()):
    a = cd.GetArray(i)
    print(a.GetName(), a.GetNumberOfComponents(), a.GetRange(-1 if a.GetNumberOfComponents() > 1 else 0))
