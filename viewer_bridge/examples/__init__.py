"""Example simulations that ship with the package: `viewer-bridge example NAME`.

Each is a real pydrake simulation (or diagram) publishing over LCM what Drake publishes: the
scene of every shape in every role, simulated cameras, contact results, a point cloud. The tests
run the same scenes. They need Drake (`pip install 'viewer-bridge[drake]'`); the rest of the
package does not, so nothing imports pydrake until an example runs. `catalog` names them and runs
one by name.
"""
