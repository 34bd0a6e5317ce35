"""The map performer: perception -> map -> goal -> path -> action, RGB only (no ROS).

`language` reads the instruction and the answers, `geometry` places what a frame shows on the
floor, `semantic_map` keeps the map and plans paths on it, `agent.MapAgent` plays an episode.
"""
