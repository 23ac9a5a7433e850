from gonio._native import version
