"""ybgc: the YARP bottle generator compiler."""
__version__ = "0.2.0"
