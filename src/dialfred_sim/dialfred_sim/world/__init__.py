"""The household world: object catalog, shapes, rooms and their pybullet bodies (ROS-free)."""
